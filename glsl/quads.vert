// The floor of this rasterizer for a frame (bench perf): the same quads as raygs.vert,
// from the same records in the same order, with nothing computed beyond the corners.
#include "splat_blocks.glsl"

uniform mat4 u_projection;

void main() {
    Splat s = this_instance_splat();
    if (s.center_c2.w == 0.0) {
        gl_Position = vec4(0.0);
        return;
    }
    vec2 corner = quad_corner();
    gl_Position = u_projection * vec4(s.center_c2.xyz + corner.x * s.axis0_half.xyz + corner.y * s.axis1_opacity.xyz, 1.0);
}
