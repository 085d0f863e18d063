// One output channel as a picture for the eye, the GPU twin of
// render/channel_pictures.py: from a geometry target's attachments (render/gl/geometry.py:
// colour; depth sum, median where found, found; normal sum) to RGB in 0..1, alpha 1,
// with no read-back. CHANNEL: 1 alpha (grey), 2 depth, 3 median depth (viridis over
// u_range, near bright, black where undefined), 4 normal (0.5 + 0.5 n in u_to_space).
// SAMPLES 1 writes instead the depths an automatic range is taken from (every u_step-th
// pixel of every u_step-th row from the top, as depth_samples takes them) into R.
// Depth and normal pixels whose alpha is below u_alpha_threshold are black, undefined,
// in the samples too (an automatic range ignores them), as shown() masks them on the CPU.
// Texels come from the interpolated uv (see present.frag for why not gl_FragCoord).
uniform sampler2D u_color;
uniform sampler2D u_depth;
uniform sampler2D u_normal;
uniform sampler2D u_palette;   // 256 x 1 viridis
uniform vec2 u_range;          // near, far
uniform mat3 u_to_space;       // camera -> the normals' space
uniform int u_step;
uniform ivec2 u_samples;       // the sample target's size
uniform float u_alpha_threshold;
in vec2 v_uv;
out vec4 out_color;

float depth_at(ivec2 p) {
    vec4 d = texelFetch(u_depth, p, 0);
    float alpha = texelFetch(u_color, p, 0).a;
    if (alpha < u_alpha_threshold) {
        return 0.0;
    }
#if CHANNEL == 3
    return d.z > 0.0 ? d.y / d.z : 0.0;
#else
    return alpha > 0.0 ? d.x / alpha : 0.0;
#endif
}

void main() {
    ivec2 size = textureSize(u_color, 0);
#if SAMPLES
    ivec2 q = clamp(ivec2(floor(v_uv * vec2(u_samples))), ivec2(0), u_samples - 1);
    out_color = vec4(depth_at(ivec2(q.x * u_step, size.y - 1 - q.y * u_step)), 0.0, 0.0, 1.0);
#else
    ivec2 p = clamp(ivec2(floor(v_uv * vec2(size))), ivec2(0), size - 1);
#if CHANNEL == 1
    out_color = vec4(vec3(clamp(texelFetch(u_color, p, 0).a, 0.0, 1.0)), 1.0);
#elif CHANNEL == 4
    float alpha = texelFetch(u_color, p, 0).a;
    vec3 n = texelFetch(u_normal, p, 0).xyz;
    float len = length(n);
    out_color = vec4(alpha > 0.0 && alpha >= u_alpha_threshold && len > 0.0 ? 0.5 + 0.5 * (u_to_space * (n / len)) : vec3(0.0), 1.0);
#else
    float z = depth_at(p);
    float position = clamp((u_range.y - z) / (u_range.y - u_range.x), 0.0, 1.0);
    vec3 shown = texelFetch(u_palette, ivec2(int(floor(position * 255.0 + 0.5)), 0), 0).rgb;
    out_color = vec4(z > 0.0 ? shown : vec3(0.0), 1.0);
#endif
#endif
}
