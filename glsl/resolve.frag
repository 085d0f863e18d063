// From the render target to the image: averages each k x k block of samples
// (supersampling's box filter) and, after front-to-back compositing, adds the
// background behind the remaining transmittance and removes the cut-off mark.
// GEOMETRY: the geometry attachments (1, 2) are averaged too: their sums, and the
// median as the mean of (z where found, else 0) and of found (render/gl/geometry.py).
// Texels come from the interpolated uv (see present.frag for why not gl_FragCoord).
// UNORM8_TARGET: the target stores 8 bits (a headset's swapchain image): the colour is
// rounded here as a screenshot rounds the float32 image (half to even), so the bits
// stored are the screenshot's whatever this GL's own float-to-unorm conversion does.
uniform sampler2D u_samples;
uniform int u_factor;  // k
uniform vec3 u_background;
in vec2 v_uv;
layout(location = 0) out vec4 out_color;
#if GEOMETRY
uniform sampler2D u_depth;
uniform sampler2D u_normal;
layout(location = 1) out vec4 out_depth;
layout(location = 2) out vec4 out_normal;
#endif

void main() {
    ivec2 size = textureSize(u_samples, 0) / u_factor;
    ivec2 pixel = clamp(ivec2(floor(v_uv * vec2(size))), ivec2(0), size - 1);
    vec4 sum = vec4(0.0);
#if GEOMETRY
    vec4 depth = vec4(0.0), normal = vec4(0.0);
#endif
    for (int j = 0; j < u_factor; ++j) {
        for (int i = 0; i < u_factor; ++i) {
            ivec2 at = pixel * u_factor + ivec2(i, j);
            vec4 s = texelFetch(u_samples, at, 0);
#if FRONT_TO_BACK
            if (s.a < -0.5) s.a += 2.0;
            s.rgb += (1.0 - s.a) * u_background;
#endif
            sum += s;
#if GEOMETRY
            depth += texelFetch(u_depth, at, 0);
            normal += texelFetch(u_normal, at, 0);
#endif
        }
    }
    float samples = float(u_factor * u_factor);
    out_color = sum / samples;
#if UNORM8_TARGET
    out_color.rgb = roundEven(clamp(out_color.rgb, 0.0, 1.0) * 255.0) / 255.0;
#endif
#if GEOMETRY
    out_depth = depth / samples;
    out_normal = normal / samples;
#endif
}
