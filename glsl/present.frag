// Shows the float render target 1:1. The texel comes from the interpolated uv, not
// from gl_FragCoord: Mesa 22's llvmpipe sometimes keeps the window's flipped
// gl_FragCoord convention for the first draw into a texture after a swap.
// Its RGB is already composited over the background, so alpha is dropped.
//
// The A/B split view: columns whose centre lies right of u_split (a fraction of the
// viewport's width, a whole number of columns) show u_right instead of u_image; both
// have the viewport's size. u_split >= 1 shows u_image alone.
uniform sampler2D u_image;
uniform sampler2D u_right;
uniform float u_split;
in vec2 v_uv;
out vec4 out_color;

void main() {
    ivec2 size = textureSize(u_image, 0);
    ivec2 texel = clamp(ivec2(floor(v_uv * vec2(size))), ivec2(0), size - 1);
    vec3 rgb = v_uv.x < u_split ? texelFetch(u_image, texel, 0).rgb : texelFetch(u_right, texel, 0).rgb;
    out_color = vec4(clamp(rgb, 0.0, 1.0), 1.0);
}
