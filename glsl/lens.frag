// The lens pre-distortion of one eye image (raygs_viewer/lens_preview.py defines it;
// lens_warp_reference is the float64 version this must match).
// Bilinear filtering is done here with texelFetch, not by the sampler: hardware
// filtering quantises the weights (to 8 bits on many GPUs) and differs by driver.
// Both textures are stored bottom row first, so image row y is texel row H - 1 - y.
// The pixel comes from the interpolated uv (see present.frag for why not gl_FragCoord).
uniform sampler2D u_image;  // the eye image, the target's size
uniform vec2 u_center;      // lens centre (cx, cy), image coordinates
uniform float u_radius;     // R
uniform float u_k1;
uniform float u_k2;
uniform float u_edge_gain;  // F = 1 + k1 + k2
uniform vec3 u_scales;      // per channel: red, green (1), blue
in vec2 v_uv;
out vec4 out_color;

float bilinear(ivec2 size, int channel, vec2 q) {
    vec2 u = q - 0.5;
    vec2 i0 = floor(u);
    vec2 f = u - i0;
    ivec2 lo = clamp(ivec2(i0), ivec2(0), size - 1);
    ivec2 hi = clamp(ivec2(i0) + 1, ivec2(0), size - 1);
    int row_lo = size.y - 1 - lo.y;
    int row_hi = size.y - 1 - hi.y;
    float top = (1.0 - f.x) * texelFetch(u_image, ivec2(lo.x, row_lo), 0)[channel]
              + f.x * texelFetch(u_image, ivec2(hi.x, row_lo), 0)[channel];
    float bottom = (1.0 - f.x) * texelFetch(u_image, ivec2(lo.x, row_hi), 0)[channel]
                 + f.x * texelFetch(u_image, ivec2(hi.x, row_hi), 0)[channel];
    return (1.0 - f.y) * top + f.y * bottom;
}

void main() {
    ivec2 size = textureSize(u_image, 0);
    ivec2 texel = clamp(ivec2(floor(v_uv * vec2(size))), ivec2(0), size - 1);
    vec2 pixel_center = vec2(float(texel.x) + 0.5, float(size.y - texel.y) - 0.5);
    vec2 d = pixel_center - u_center;
    vec2 p = d / u_radius;
    float r2 = dot(p, p);
    // d times a gain, as source_point does: the identity lens maps pixels exactly.
    float gain = (1.0 + r2 * (u_k1 + u_k2 * r2)) / u_edge_gain;
    vec4 color = vec4(0.0);
    for (int c = 0; c < 3; ++c) {
        vec2 q = u_center + d * (gain * u_scales[c]);
        bool inside = all(greaterThanEqual(q, vec2(0.0))) && all(lessThanEqual(q, vec2(size)));
        if (inside) {
            color[c] = bilinear(size, c, q);
            if (c == 1) color.a = 1.0;
        }
    }
    out_color = color;
}
