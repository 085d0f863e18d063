// The per-view record the preprocessing pass writes once per gaussian and the
// vertex stage reads four times: everything the quad and the fragments need.
struct Splat {
    vec4 center_c2;   // camera-space centre mu (OpenCV axes), c^2 (0: not drawn)
    vec4 axis0_half;  // camera-space half-axis of the quad, and its half-size r
    vec4 axis1_opacity; // the other half-axis, and the opacity o
    vec4 color;       // RGB from SH for this view, a = unused
};
