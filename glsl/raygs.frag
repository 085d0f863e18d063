#include "fragment_output.glsl"
// The ray's divergence from the quad coordinate (maths page, section 5, Eq. 16).
// EXACT_MIP: the pixel-dependent MIP filter (section 6, Appendix A.5), evaluated in
// the gaussian's rotated frame, where the covariance is diag(s^2) and the filter
// sigma_x^2 tau^2 I only widens the scales.
in vec2 v_plane;
flat in vec4 v_color_opacity;
flat in vec2 v_inv_c2_kappa;
#if PER_PIXEL || GEOMETRY
in vec3 v_point;              // the quad point in camera space
#endif
#if GEOMETRY && !PER_PIXEL
flat in vec3 v_normal;        // the shortest axis, to be turned to face this ray
#endif

// The fragment's geometry outputs (docs/geometry.md): the z of its peak at t* on the unit
// ray, and the normal facing the ray. Only the GEOMETRY blend reads them.
void emit_peak(vec3 rgb, float alpha, float t_star) {
#if GEOMETRY && !PER_PIXEL
    vec3 ray = normalize(v_point);
    vec3 normal = dot(v_normal, ray) > 0.0 ? -v_normal : v_normal;
    emit_geometry(rgb, alpha, t_star, t_star * ray.z, normal);
#else
    emit_at(rgb, alpha, t_star);
#endif
}
#if EXACT_MIP
in vec3 v_offset;             // the quad point relative to the centre (rotated frame)
flat in vec3 v_local_center;
flat in vec3 v_scale;
uniform float u_pixel_variance;  // sigma_x^2: the filter's variance at unit distance
#endif

void main() {
    float r2 = dot(v_plane, v_plane);
    float divergence = r2 / (1.0 + r2 * v_inv_c2_kappa.x);
    // Outside the support (D > kappa) the opacity is below p_min: no exp to find that out.
    // EXACT_MIP: the quad bounds the support of the widest filter this gaussian can get;
    // outside that support the exact opacity is below p_min too.
    if (divergence > v_inv_c2_kappa.y) discard;
#if EXACT_MIP
    vec3 point = v_local_center + v_offset;                // on the pixel's ray
    vec3 ray = normalize(point);
    vec3 s2 = v_scale * v_scale;
    float ray_metric = dot(ray * ray, 1.0 / s2);            // x^T Sigma^-1 x
    float tau = dot(ray * v_local_center, 1.0 / s2) / ray_metric;
    if (tau <= 0.0) discard;                                // the peak is behind the camera
    vec3 s2_hat = s2 + u_pixel_variance * tau * tau;
    vec3 s_hat = sqrt(s2_hat);
    // D = |y x w|^2 / |y|^2 with y = point / s_hat. y x w = (offset / s_hat) x w, since
    // w x w = 0: far from the camera y and w are nearly parallel and their cross
    // product would cancel to the float32 noise of |w| (maths page, section 8).
    vec3 y = point / s_hat, w = v_local_center / s_hat;
    vec3 across = cross(v_offset / s_hat, w);
    divergence = dot(across, across) / dot(y, y);
    float opacity = v_color_opacity.a;
    if (MIP_MODULATION) {
        // sqrt(|Sigma| x^T Sigma^-1 x / (|Sigma_hat| x^T Sigma_hat^-1 x)), as a product of
        // ratios <= 1 so tiny scales do not underflow a determinant.
        vec3 shrink = s2 / s2_hat;
        opacity *= sqrt(shrink.x * shrink.y * shrink.z * ray_metric / dot(ray * ray, 1.0 / s2_hat));
    }
    // t* (section 11) with this pixel's filtered scales, along the unit ray.
    float t_star = 0.0;
#if PER_PIXEL || GEOMETRY
    t_star = dot(ray * v_local_center, 1.0 / s2_hat) / dot(ray * ray, 1.0 / s2_hat);
#endif
    emit_peak(v_color_opacity.rgb, opacity * exp(-0.5 * divergence), t_star);
#else
    // t* (section 11) along the unit ray: the whitened quad point y satisfies y.w = c^2
    // and |y|^2 = c^2 + r^2, so t*(q) = c^2 / (c^2 + r^2) and t* = |q| / (1 + r^2 / c^2).
    float t_star = 0.0;
#if PER_PIXEL || GEOMETRY
    t_star = length(v_point) / (1.0 + r2 * v_inv_c2_kappa.x);
#endif
    emit_peak(v_color_opacity.rgb, v_color_opacity.a * exp(-0.5 * divergence), t_star);
#endif
}
