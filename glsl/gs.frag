#include "fragment_output.glsl"
// The projected 2D gaussian at the pixel centre (the offset is exact there: the quad
// is drawn in image space with w = 1, so interpolation is linear).
in vec2 v_offset;
flat in vec4 v_conic_opacity;
flat in vec3 v_color;
#if GEOMETRY && !PER_PIXEL
in vec2 v_pixel;
flat in vec4 v_normal_depth;
uniform vec4 u_intrinsics;  // fx, fy, cx, cy of the camera drawn
#endif

void main() {
    vec2 d = v_offset;
    vec3 conic = v_conic_opacity.xyz;
    float power = conic.x * d.x * d.x + 2.0 * conic.y * d.x * d.y + conic.z * d.y * d.y;
#if GEOMETRY && !PER_PIXEL
    // EWA has no t*: the centre's z, as the 3DGS renderer's depth.
    vec3 ray = vec3((v_pixel - u_intrinsics.zw) / u_intrinsics.xy, 1.0);
    vec3 normal = dot(v_normal_depth.xyz, ray) > 0.0 ? -v_normal_depth.xyz : v_normal_depth.xyz;
    emit_geometry(v_color, v_conic_opacity.w * exp(-0.5 * power), 0.0, v_normal_depth.w, normal);
#else
    emit(v_color, v_conic_opacity.w * exp(-0.5 * power));
#endif
}
