// The sorted order and the splat records, for the vertex stages (and, with SPLATS_ONLY
// defined, for any stage that reads a record by its index). The records span
// SPLAT_BLOCKS bindings of SPLATS_PER_BLOCK each, so a large scene never exceeds the
// per-block storage limit.
#include "splat.glsl"

layout(std430, binding = 0) readonly buffer Order { uint order[]; };
// Each binding is spelt out: a layout binding must be a literal in GLSL 4.30, and token
// pasting (##), which could generate them, is not portable GLSL.
#if SPLAT_BLOCKS < 1 || SPLAT_BLOCKS > 8
#error SPLAT_BLOCKS must be 1 to 8 (render/gl/storage.py, MAX_SPLAT_BLOCKS)
#endif
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

uniform uint u_order_count;

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

#ifndef SPLATS_ONLY  // the vertex stages'; fragment and compute stages read records by index only
// DRAW_VERTICES (render/gl/plan.py): 0, one instance of a 4-vertex strip per quad; 1, an
// index buffer of 6 indices over vertices 4q .. 4q + 3 per quad; 2, 6 vertices per quad
// and no buffer. The two triangles are the strip's own, (0, 1, 2) and (2, 1, 3), so every
// layout rasterizes the same triangles in the same order.
uint draw_slot() {
#if DRAW_VERTICES == 1
    return uint(gl_VertexID) >> 2;
#elif DRAW_VERTICES == 2
    return uint(gl_VertexID) / 6u;
#else
    return uint(gl_InstanceID);
#endif
}

// The order is back to front; the transmittance cut-off and the per-pixel order
// draw it front to back (so the draw slot is the rank in the front-to-back order).
uint draw_place() {
#if FRONT_TO_BACK || PER_PIXEL
    return u_order_count - 1u - draw_slot();
#else
    return draw_slot();
#endif
}

uint this_instance_index() {
    return order[draw_place()];
}

// RECORDS_IN_DRAW_ORDER: the preprocessing pass wrote each record at its place in the
// order, so the draw reads them in sequence.
Splat this_instance_splat() {
#if RECORDS_IN_DRAW_ORDER
    return fetch_splat(draw_place());
#else
    return fetch_splat(this_instance_index());
#endif
}

// Corners (-,-), (+,-), (-,+), (+,+), in the triangle strip's order.
vec2 quad_corner() {
#if DRAW_VERTICES == 1
    int corner = gl_VertexID & 3;
#elif DRAW_VERTICES == 2
    const int strip_corner[6] = int[6](0, 1, 2, 2, 1, 3);
    int corner = strip_corner[gl_VertexID % 6];
#else
    int corner = gl_VertexID;
#endif
    return vec2((corner & 1) != 0 ? 1.0 : -1.0, (corner & 2) != 0 ? 1.0 : -1.0);
}
#endif
