// EWA splatting (maths page, section 7): one image-space quad per visible gaussian,
// in sorted order, spanning the kappa-ellipse of its projected 2D covariance.
#include "splat_blocks.glsl"

uniform vec2 u_image_size;  // pixels

// Pixels from the projected centre. Every w is 1, so ordinary interpolation is linear
// in screen space; llvmpipe (Mesa 22.3) mis-interpolates `noperspective` varyings on
// triangles it clips, so that qualifier is not used.
out vec2 v_offset;
flat out vec4 v_conic_opacity;
flat out vec3 v_color;
#if GEOMETRY && !PER_PIXEL
out vec2 v_pixel;            // image coordinates (v downwards): the fragment's ray
flat out vec4 v_normal_depth;  // the shortest axis, and the centre's camera-space z
#endif
#if PER_PIXEL
// The geometry outputs of the global order go through fragment lists (count, then fill
// per part: every pass must keep exactly the same fragments), sorted by rank.
invariant gl_Position;
flat out uint v_index;
flat out uint v_rank;
#elif WEIGHTS
flat out uint v_index;       // the gaussian's scene index: the weight's slot (render/gl/weighing.py)
#endif

void main() {
#if PER_PIXEL
    v_index = this_instance_index();
    v_rank = draw_slot();
    Splat s = fetch_splat(v_index);
#else
    Splat s = this_instance_splat();
#if WEIGHTS
    v_index = this_instance_index();
#endif
#endif
    v_conic_opacity = s.axis1_opacity;
    v_color = s.color.rgb;
#if GEOMETRY && !PER_PIXEL
    v_normal_depth = vec4(s.normal.xyz, s.center_c2.z);
    v_pixel = vec2(0.0);
#endif
    if (s.center_c2.w == 0.0) {
        gl_Position = vec4(0.0);
        v_offset = vec2(0.0);
        return;
    }
    vec2 corner = quad_corner();
    v_offset = corner.x * s.axis0_half.xy + corner.y * s.axis0_half.zw;
    vec2 pixel = s.center_c2.xy + v_offset;  // image coordinates, v downwards
#if GEOMETRY && !PER_PIXEL
    v_pixel = pixel;
#endif
    gl_Position = vec4(2.0 * pixel.x / u_image_size.x - 1.0, 1.0 - 2.0 * pixel.y / u_image_size.y, 0.0, 1.0);
}
