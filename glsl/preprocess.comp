// Per gaussian, per view: colour, opacity, c^2 and the RayGS quad frame
// (maths page, sections 3 and 4). Runs over one chunk of gaussians at a time so
// that no bound range exceeds the per-block storage limit.
layout(local_size_x = 128) in;

#include "splat.glsl"

struct Gaussian {
    vec4 position_opacity;
    vec4 scale;      // xyz: linear standard deviations
    vec4 rotation;   // unit quaternion (w, x, y, z)
};

layout(std430, binding = 0) readonly buffer Gaussians { Gaussian gaussians[]; };
layout(std430, binding = 1) readonly buffer Harmonics { float harmonics[]; };
layout(std430, binding = 2) writeonly buffer Splats { Splat splats[]; };

uniform uint u_count;        // gaussians in this chunk
uniform uint u_out_offset;   // first output slot of this chunk within the bound range
uniform mat3 u_world_to_camera;
uniform vec3 u_camera_center;
uniform float u_log_p_min;

// The scene stores SH_STORED_DEGREE bands; SH_DEGREE (<= it) are evaluated.
const uint COEFFS = uint((SH_STORED_DEGREE + 1) * (SH_STORED_DEGREE + 1));
uint g_index;
vec3 coeff(int k) {
    uint base = (g_index * COEFFS + uint(k)) * 3u;
    return vec3(harmonics[base], harmonics[base + 1u], harmonics[base + 2u]);
}
#include "sh.glsl"

mat3 quaternion_matrix(vec4 q) {
    float w = q.x, x = q.y, y = q.z, z = q.w;
    // Columns, as GLSL's mat3 constructor takes them.
    return mat3(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
                2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
                2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    g_index = i;
    Gaussian g = gaussians[i];
    vec3 scale = g.scale.xyz;
    float opacity = g.position_opacity.w;
    vec3 offset = g.position_opacity.xyz - u_camera_center;  // world, camera -> centre
    mat3 rotation = quaternion_matrix(g.rotation);

    // Whitened frame: there the gaussian is a unit sphere at w, seen from the origin.
    vec3 w = (transpose(rotation) * offset) / scale;
    float c2 = dot(w, w);
    float kappa = 2.0 * (log(opacity) - u_log_p_min);  // exact log (maths page, section 3)

    Splat s;
    s.color = vec4(sh_color(normalize(offset)), 0.0);
    s.center_c2 = vec4(u_world_to_camera * offset, 0.0);
    s.axis0_half = vec4(0.0);
    s.axis1_opacity = vec4(0.0, 0.0, 0.0, opacity);
    if (kappa > 0.0 && c2 > kappa) {
        vec3 m = w * inversesqrt(c2);
        float b = sqrt(1.0 - kappa / c2);
        float half_size = sqrt(kappa) / b;
        // Rotation taking e_z to m, its first two columns (stable Householder form).
        float sigma = m.z >= 0.0 ? 1.0 : -1.0;
        vec3 h = vec3(m.xy, m.z + sigma);
        float k = 2.0 / dot(h, h);
        vec3 col0 = sigma * (k * h.x * h - vec3(1.0, 0.0, 0.0));
        vec3 col1 = k * h.y * h - vec3(0.0, 1.0, 0.0);
        // Align the square with the principal axes of the ellipse it bounds:
        // B = Q2^T Q2 with Q2 = Rp S [col0 col1] (rotations drop out).
        vec3 q0 = scale * col0, q1 = scale * col1;
        float b00 = dot(q0, q0), b11 = dot(q1, q1), b01 = dot(q0, q1);
        float angle = (b01 == 0.0 && b00 == b11) ? 0.0 : 0.5 * atan(2.0 * b01, b00 - b11);
        vec2 u1 = vec2(cos(angle), sin(angle));
        vec2 u0 = vec2(-u1.y, u1.x);
        mat3 to_camera = u_world_to_camera * rotation;
        s.center_c2.w = c2;
        s.axis0_half = vec4(to_camera * ((q0 * u0.x + q1 * u0.y) * half_size), half_size);
        s.axis1_opacity.xyz = to_camera * ((q0 * u1.x + q1 * u1.y) * half_size);
    }
    splats[u_out_offset + i] = s;
}
