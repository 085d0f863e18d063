// One image of a stereo pair, texel for texel as raygs_viewer.stereo.compose builds it.
// The target is u_halves eye widths wide; in half h, channel i comes from the right eye
// where u_from_right[h][i] is set, else from the left. Selection, not arithmetic, so
// every value (NaN and Inf too) is copied bit for bit.
// Both eyes and the target are stored bottom row first, so rows copy straight across.
// The pixel comes from the interpolated uv (see present.frag for why not gl_FragCoord).
uniform sampler2D u_left;
uniform sampler2D u_right;
uniform int u_halves;           // 2 for side by side layouts, else 1
uniform ivec4 u_from_right[2];
in vec2 v_uv;
out vec4 out_color;

void main() {
    ivec2 eye = textureSize(u_left, 0);
    ivec2 size = ivec2(eye.x * u_halves, eye.y);
    ivec2 pixel = clamp(ivec2(floor(v_uv * vec2(size))), ivec2(0), size - 1);
    int half_index = pixel.x / eye.x;
    ivec2 texel = ivec2(pixel.x - half_index * eye.x, pixel.y);
    out_color = mix(texelFetch(u_left, texel, 0), texelFetch(u_right, texel, 0),
                    notEqual(u_from_right[half_index], ivec4(0)));
}
