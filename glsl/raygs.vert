// One instanced quad per visible gaussian, in sorted order (maths page, section 4).
#include "splat.glsl"

layout(std430, binding = 0) readonly buffer Order { uint order[]; };

// The splat records span SPLAT_BLOCKS bindings of SPLATS_PER_BLOCK each, so a
// large scene never exceeds the per-block storage limit.
layout(std430, binding = 1) readonly buffer Splats0 { Splat splats0[]; };
#if SPLAT_BLOCKS > 1
layout(std430, binding = 2) readonly buffer Splats1 { Splat splats1[]; };
#endif
#if SPLAT_BLOCKS > 2
layout(std430, binding = 3) readonly buffer Splats2 { Splat splats2[]; };
#endif
#if SPLAT_BLOCKS > 3
layout(std430, binding = 4) readonly buffer Splats3 { Splat splats3[]; };
#endif
#if SPLAT_BLOCKS > 4
layout(std430, binding = 5) readonly buffer Splats4 { Splat splats4[]; };
#endif
#if SPLAT_BLOCKS > 5
layout(std430, binding = 6) readonly buffer Splats5 { Splat splats5[]; };
#endif
#if SPLAT_BLOCKS > 6
layout(std430, binding = 7) readonly buffer Splats6 { Splat splats6[]; };
#endif
#if SPLAT_BLOCKS > 7
layout(std430, binding = 8) readonly buffer Splats7 { Splat splats7[]; };
#endif

Splat fetch_splat(uint index) {
    uint block = index / uint(SPLATS_PER_BLOCK);
    uint i = index - block * uint(SPLATS_PER_BLOCK);
#if SPLAT_BLOCKS > 1
    if (block == 1u) return splats1[i];
#endif
#if SPLAT_BLOCKS > 2
    if (block == 2u) return splats2[i];
#endif
#if SPLAT_BLOCKS > 3
    if (block == 3u) return splats3[i];
#endif
#if SPLAT_BLOCKS > 4
    if (block == 4u) return splats4[i];
#endif
#if SPLAT_BLOCKS > 5
    if (block == 5u) return splats5[i];
#endif
#if SPLAT_BLOCKS > 6
    if (block == 6u) return splats6[i];
#endif
#if SPLAT_BLOCKS > 7
    if (block == 7u) return splats7[i];
#endif
    return splats0[i];
}

uniform mat4 u_projection;  // OpenCV camera space -> clip space

out vec2 v_plane;            // position in the quad's plane, whitened units (z of Eq. 16)
flat out vec4 v_color_opacity;
flat out float v_c2;

void main() {
    Splat s = fetch_splat(order[gl_InstanceID]);
    v_color_opacity = vec4(s.color.rgb, s.axis1_opacity.w);
    v_c2 = s.center_c2.w;
    if (s.center_c2.w == 0.0) {  // not drawn: a degenerate quad makes no fragments
        gl_Position = vec4(0.0);
        v_plane = vec2(0.0);
        return;
    }
    // Triangle-strip corners (-,-), (+,-), (-,+), (+,+).
    vec2 corner = vec2((gl_VertexID & 1) != 0 ? 1.0 : -1.0, (gl_VertexID & 2) != 0 ? 1.0 : -1.0);
    vec3 position = s.center_c2.xyz + corner.x * s.axis0_half.xyz + corner.y * s.axis1_opacity.xyz;
    v_plane = corner * s.axis0_half.w;
    gl_Position = u_projection * vec4(position, 1.0);
}
