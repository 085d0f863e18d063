// The per-view record the preprocessing pass writes once per gaussian and the
// vertex stage reads four times: everything the quad and the fragments need.
// RayGS (raygs.vert):
//   center_c2     camera-space centre mu (OpenCV axes), c^2 (0: not drawn)
//   axis0_half    camera-space half-axis of the quad, and its half-size r
//   axis1_opacity the other half-axis, and the opacity o
//   color         RGB from SH for this view; a = kappa
// EXACT_MIP adds the quad in the gaussian's own rotated (unscaled) frame, where the
// fragment stage evaluates the pixel-dependent filter:
//   local_center  Rp^T mu, and s.x;  local_axis0 / local_axis1: Rp^T of the half-axes, s.y / s.z
// EWA splatting (gs.vert) uses the same four vec4, in pixels:
//   center_c2     projected centre (u, v), camera-space depth, 1 (0: not drawn)
//   axis0_half    the quad's two half-axes (xy, zw)
//   axis1_opacity the inverse 2D covariance (xx, xy, yy) and the opacity
//   color         RGB
// GEOMETRY (the depth and normal outputs, docs/geometry.md) adds, in every mode:
//   normal        the gaussian's shortest axis in camera space (xyz), not yet turned to
//                 face a ray (each sample turns it to its own)
struct Splat {
    vec4 center_c2;
    vec4 axis0_half;
    vec4 axis1_opacity;
    vec4 color;
#if EXACT_MIP
    vec4 local_center;
    vec4 local_axis0;
    vec4 local_axis1;
#endif
#if GEOMETRY
    vec4 normal;
#endif
};
