// From the render target to the image: averages each k x k block of samples
// (supersampling's box filter) and, after front-to-back compositing, adds the
// background behind the remaining transmittance and removes the cut-off mark.
// Texels come from the interpolated uv (see present.frag for why not gl_FragCoord).
uniform sampler2D u_samples;
uniform int u_factor;  // k
uniform vec3 u_background;
in vec2 v_uv;
out vec4 out_color;

void main() {
    ivec2 size = textureSize(u_samples, 0) / u_factor;
    ivec2 pixel = clamp(ivec2(floor(v_uv * vec2(size))), ivec2(0), size - 1);
    vec4 sum = vec4(0.0);
    for (int j = 0; j < u_factor; ++j) {
        for (int i = 0; i < u_factor; ++i) {
            vec4 s = texelFetch(u_samples, pixel * u_factor + ivec2(i, j), 0);
#if FRONT_TO_BACK
            if (s.a < -0.5) s.a += 2.0;
            s.rgb += (1.0 - s.a) * u_background;
#endif
            sum += s;
        }
    }
    out_color = sum / float(u_factor * u_factor);
}
