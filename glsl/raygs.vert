// One quad per visible gaussian, in sorted order (maths page, section 4).
#include "splat_blocks.glsl"

uniform mat4 u_projection;  // OpenCV camera space -> clip space

#if PER_PIXEL
// The per-pixel order draws the same quads in several passes (count, then fill per
// part); each pass must keep exactly the same fragments.
invariant gl_Position;
flat out uint v_index;       // the gaussian's scene index: its record, and the tie-break
flat out uint v_rank;        // its place in the global front-to-back order
#endif
#if WEIGHTS && !PER_PIXEL
flat out uint v_index;       // the gaussian's scene index: the weight's slot (render/gl/weighing.py)
#endif
#if PER_PIXEL || GEOMETRY
out vec3 v_point;            // the quad point in camera space, for t* (section 11)
#endif
#if GEOMETRY && !PER_PIXEL
flat out vec3 v_normal;      // the shortest axis (the lists' resolve reads it from the record)
#endif

out vec2 v_plane;            // position in the quad's plane, whitened units (z of Eq. 16)
flat out vec4 v_color_opacity;
flat out vec2 v_inv_c2_kappa;  // 1 / c^2 (one division per quad, not per fragment), kappa
#if EXACT_MIP
out vec3 v_offset;           // the quad point minus the centre, in the gaussian's rotated frame
flat out vec3 v_local_center;
flat out vec3 v_scale;
#endif

void main() {
#if PER_PIXEL
    v_index = this_instance_index();
    v_rank = draw_slot();
    Splat s = fetch_splat(v_index);
#else
    Splat s = this_instance_splat();
#endif
#if WEIGHTS && !PER_PIXEL
    v_index = this_instance_index();
#endif
#if PER_PIXEL || GEOMETRY
    v_point = vec3(0.0);
#endif
#if GEOMETRY && !PER_PIXEL
    v_normal = s.normal.xyz;
#endif
    v_color_opacity = vec4(s.color.rgb, s.axis1_opacity.w);
    v_inv_c2_kappa = vec2(1.0 / s.center_c2.w, s.color.a);
#if EXACT_MIP
    v_local_center = s.local_center.xyz;
    v_scale = vec3(s.local_center.w, s.local_axis0.w, s.local_axis1.w);
    v_offset = vec3(0.0);
#endif
    if (s.center_c2.w == 0.0) {  // not drawn: a degenerate quad makes no fragments
        gl_Position = vec4(0.0);
        v_plane = vec2(0.0);
        return;
    }
    vec2 corner = quad_corner();
    vec3 position = s.center_c2.xyz + corner.x * s.axis0_half.xyz + corner.y * s.axis1_opacity.xyz;
    v_plane = corner * s.axis0_half.w;
#if PER_PIXEL || GEOMETRY
    v_point = position;
#endif
#if EXACT_MIP
    v_offset = corner.x * s.local_axis0.xyz + corner.y * s.local_axis1.xyz;
#endif
    gl_Position = u_projection * vec4(position, 1.0);
}
