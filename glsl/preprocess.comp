// Per gaussian, per view: colour, opacity and the quad to draw (maths page, sections
// 3 to 7). Runs over one chunk of gaussians at a time so that no bound range exceeds
// the per-block storage limit. Variants, by #define:
//   MODE_GS          EWA splatting's image-space quad (section 7), GS_COMPENSATION
//   MIP              RayGS with the pixel-invariant MIP filter (Eq. 17), MIP_MODULATION
//   EXACT_MIP        RayGS with the pixel-dependent filter: the quad bounds the widest
//                    filter a pixel can apply; the fragments evaluate the filter.
// Feature switches (features.glsl): SH_DEGREE, MIP, MIP_MODULATION, GS_COMPENSATION;
// COLOR_AT_LOAD: binding 1 holds each gaussian's RGB (and a pad), computed once at load
// (SH degree 0 is view-independent), instead of SH coefficients.
// RECORDS_IN_DRAW_ORDER: the pass runs over places in the order instead of gaussians, and
// writes each record at its place (render/gl/plan.py, RECORDS); culled gaussians cost nothing.
// SELECTION: the window's selected gaussians (one bit each at binding 5) are drawn with
// their colour halfway to the tint: the selection is seen in the picture itself, the
// scene's buffers untouched (render/gl/storage.py, set_selection).
layout(local_size_x = 128) in;

#include "features.glsl"
#include "splat.glsl"

struct Gaussian {
    vec4 position_opacity;
    vec4 scale;      // xyz: linear standard deviations
    vec4 rotation;   // unit quaternion (w, x, y, z)
};

layout(std430, binding = 0) readonly buffer Gaussians { Gaussian gaussians[]; };
layout(std430, binding = 1) readonly buffer Harmonics { float harmonics[]; };
layout(std430, binding = 2) writeonly buffer Splats { Splat splats[]; };

uniform uint u_first;        // first gaussian of this dispatch within the chunk (a level-of-detail
                             // choice preprocesses only the spans it draws)
uniform uint u_count;        // gaussians in this dispatch
uniform uint u_out_offset;   // first output slot of this chunk within the bound range
#if RECORDS_IN_DRAW_ORDER
// This dispatch's places are u_first .. u_first + u_count - 1, or, u_ranked, the places
// u_ranks holds there: those whose gaussian is in the bound chunk of the scene (from row
// u_chunk_start, u_chunk_rows rows) and whose record is in the bound splat block (from
// place u_block_start). An order kept on the GPU is not grouped by chunk (that would read
// it back): its places run once per chunk, and a place whose gaussian is in another
// chunk writes nothing (render/gl/storage.py, spread_runs).
layout(std430, binding = 3) readonly buffer Order { uint order[]; };
layout(std430, binding = 4) readonly buffer Ranks { uint ranks[]; };
uniform bool u_ranked;
uniform uint u_chunk_start;
uniform uint u_chunk_rows;
uniform uint u_block_start;
#endif
#if SELECTION
layout(std430, binding = 5) readonly buffer Selection { uint selected_bits[]; };
#if !RECORDS_IN_DRAW_ORDER
uniform uint u_chunk_start;  // the scene row of the bound chunk's first gaussian
#endif
const vec3 SELECTION_TINT = vec3(1.0, 0.85, 0.0);
#endif
uniform mat3 u_world_to_camera;
uniform vec3 u_translation;   // t of the world-to-camera transform: mu = R p + t
uniform vec3 u_color_origin;  // where SH colour is seen from: the camera, or (stereo) the eyes' midpoint
uniform float u_log_p_min;
uniform float u_pixel_variance;  // MIP: sigma_x^2, the filter's variance at unit distance
uniform vec4 u_intrinsics;       // GS: fx, fy, cx, cy
uniform vec4 u_ray_bounds;       // GS: the clamp box of x/z, y/z (lower xy, upper zw)

// The largest quad half-size, in whitened units (kappa <= 2 ln(1/p_min) ~ 18 at most).
const float MAX_HALF_SIZE = 1.0e4;

// The scene stores SH_STORED_DEGREE bands; SH_DEGREE (<= it) are evaluated.
const uint COEFFS = uint((SH_STORED_DEGREE + 1) * (SH_STORED_DEGREE + 1));
uint g_index;
vec3 coeff(int k) {
    // Colours at load are padded to 16 bytes, so every chunk's range stays aligned.
    uint base = COLOR_AT_LOAD ? g_index * 4u : (g_index * COEFFS + uint(k)) * 3u;
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

#if MODE_GS
// The linearised projection at mu (INRIA's, with its ray clamped 15 % of the whole
// image beyond each border), Sigma2 = J Sigma J^T + dilation, and the quad spanning
// its kappa-ellipse along the eigenvectors.
void project_ewa(inout Splat s, vec3 mu, mat3 to_camera, vec3 scale, float opacity) {
    if (mu.z <= GS_NEAR) return;
    vec2 focal = u_intrinsics.xy, principal = u_intrinsics.zw;
    vec2 ray = clamp(mu.xy / mu.z, u_ray_bounds.xy, u_ray_bounds.zw);
    // Rows of J, taken into the gaussian's scaled frame: Sigma2 = [a b]^T [a b].
    vec3 j0 = vec3(focal.x / mu.z, 0.0, -focal.x * ray.x / mu.z);
    vec3 j1 = vec3(0.0, focal.y / mu.z, -focal.y * ray.y / mu.z);
    vec3 a = scale * (transpose(to_camera) * j0);
    vec3 b = scale * (transpose(to_camera) * j1);
    float xx = dot(a, a), xy = dot(a, b), yy = dot(b, b);
    // Determinants without cancellation: xx yy - xy^2 = |a x b|^2 (Lagrange), which
    // near the camera is a small difference of numbers around 1e12 in float32.
    vec3 normal = cross(a, b);
    float det_unfiltered = dot(normal, normal);
    float det = det_unfiltered + GS_DILATION * (xx + yy) + GS_DILATION * GS_DILATION;
    xx += GS_DILATION;
    yy += GS_DILATION;
    if (GS_COMPENSATION) opacity *= sqrt(det_unfiltered / det);
    float kappa = 2.0 * (log(opacity) - u_log_p_min);
    if (kappa <= 0.0) return;
    float mid = 0.5 * (xx + yy), radius = sqrt(0.25 * (xx - yy) * (xx - yy) + xy * xy);
    float angle = (xy == 0.0 && xx == yy) ? 0.0 : 0.5 * atan(2.0 * xy, xx - yy);
    vec2 major = vec2(cos(angle), sin(angle));
    s.center_c2 = vec4(focal * mu.xy / mu.z + principal, mu.z, 1.0);
    float major_variance = mid + radius;
    float minor_variance = det / major_variance;  // not mid - radius: that cancels
    s.axis0_half = vec4(major * sqrt(kappa * major_variance), vec2(-major.y, major.x) * sqrt(kappa * minor_variance));
    s.axis1_opacity = vec4(yy / det, -xy / det, xx / det, opacity);
}
#endif

void main() {
    if (gl_GlobalInvocationID.x >= u_count) return;
#if RECORDS_IN_DRAW_ORDER
    uint place = u_first + gl_GlobalInvocationID.x;
    if (u_ranked) place = ranks[place];
    uint i = order[place] - u_chunk_start;  // wraps past u_chunk_rows below the chunk
    if (i >= u_chunk_rows) return;
    uint slot = place - u_block_start;
#else
    uint i = u_first + gl_GlobalInvocationID.x;
    uint slot = u_out_offset + i;
#endif
    g_index = i;
    Gaussian g = gaussians[i];
    vec3 scale = g.scale.xyz;
    float opacity = g.position_opacity.w;
    mat3 rotation = quaternion_matrix(g.rotation);
    mat3 to_camera = u_world_to_camera * rotation;
    // R p + t, not R (p - C): a camera far from the origin looking at a small object
    // then keeps the object's lateral offsets at full float32 precision (only the
    // large depth rounds, relatively); p - C would round every coordinate to the
    // ulp of |C| (maths page, section 8).
    vec3 mu = u_world_to_camera * g.position_opacity.xyz + u_translation;

    Splat s;
    s.color = vec4(COLOR_AT_LOAD ? coeff(0) : sh_color(normalize(g.position_opacity.xyz - u_color_origin)),
                   0.0);
#if SELECTION
    uint row = u_chunk_start + i;
    if ((selected_bits[row >> 5u] & (1u << (row & 31u))) != 0u) s.color.rgb = mix(s.color.rgb, SELECTION_TINT, 0.5);
#endif
    s.center_c2 = vec4(mu, 0.0);
    s.axis0_half = vec4(0.0);
    s.axis1_opacity = vec4(0.0, 0.0, 0.0, opacity);
#if GEOMETRY
    // The stored scales, before any filter widens them (the filters are isotropic, so
    // they never change which axis is shortest); ties go to the first, as in the reference.
    int shortest = scale.x <= scale.y && scale.x <= scale.z ? 0 : (scale.y <= scale.z ? 1 : 2);
    s.normal = vec4(to_camera[shortest], 0.0);
#endif
#if MODE_GS
    project_ewa(s, mu, to_camera, scale, opacity);
#else
    vec3 local = transpose(to_camera) * mu;  // mu in the gaussian's rotated frame
#if EXACT_MIP
    // The quad must hold every pixel's support: bound the filter by the farthest peak.
    float kappa = 2.0 * (log(opacity) - u_log_p_min);
    vec3 s_mip = sqrt(scale * scale + u_pixel_variance * dot(mu, mu));
    float tau_max = length(mu) + sqrt(max(kappa, 0.0)) * max(max(s_mip.x, s_mip.y), s_mip.z);
    vec3 unfiltered = scale;
    scale = sqrt(scale * scale + u_pixel_variance * tau_max * tau_max);
    s.local_center = vec4(local, unfiltered.x);
    s.local_axis0 = vec4(0.0, 0.0, 0.0, unfiltered.y);
    s.local_axis1 = vec4(0.0, 0.0, 0.0, unfiltered.z);
#else
    if (MIP) {
        vec3 s_hat = sqrt(scale * scale + u_pixel_variance * dot(mu, mu));
        if (MIP_MODULATION) {
            // Eq. 17's sqrt(|Sigma| c^2 / (|Sigma_hat| c_hat^2)), as ratios that cannot underflow.
            vec3 shrink = scale / s_hat;
            // c / c_hat is 0/0 with the camera at the centre (skipped below: c^2 <= kappa);
            // 1 keeps the record finite.
            float c_hat = length(local / s_hat);
            opacity *= shrink.x * shrink.y * shrink.z * (c_hat > 0.0 ? length(local / scale) / c_hat : 1.0);
            s.axis1_opacity.w = opacity;
        }
        scale = s_hat;
    }
#endif
#if !EXACT_MIP
    float kappa = 2.0 * (log(opacity) - u_log_p_min);  // exact log (maths page, section 3)
#endif
    // Whitened frame: there the gaussian is a unit sphere at w, seen from the origin.
    vec3 w = local / scale;
    float c2 = dot(w, w);
    if (kappa > 0.0 && c2 > kappa) {
        vec3 m = w * inversesqrt(c2);
        // c2 - kappa first: exact when they are close (Sterbenz) and never <= 0 here, so
        // b > 0 even where a GPU's approximate division would take kappa / c2 to 1 or
        // beyond. The cap keeps the quad finite as c2 -> kappa: rays beyond it have
        // D > c2 (1 - c2 / MAX_HALF_SIZE^2), within float32 rounding of c2 > kappa, so
        // only fragments at the p_min threshold are lost (maths page, section 8).
        float b = sqrt((c2 - kappa) / c2);
        float half_size = min(sqrt(kappa) / b, MAX_HALF_SIZE);
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
        vec3 local_axis0 = (q0 * u0.x + q1 * u0.y) * half_size;
        vec3 local_axis1 = (q0 * u1.x + q1 * u1.y) * half_size;
        s.center_c2.w = c2;
        s.color.a = kappa;
        s.axis0_half = vec4(to_camera * local_axis0, half_size);
        s.axis1_opacity.xyz = to_camera * local_axis1;
#if EXACT_MIP
        s.local_axis0.xyz = local_axis0;
        s.local_axis1.xyz = local_axis1;
#endif
    }
#endif
    splats[slot] = s;
}
