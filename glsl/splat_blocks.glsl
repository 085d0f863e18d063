// The sorted order and the splat records, for the vertex stages (and, with SPLATS_ONLY
// defined, for any stage that reads a record by its index). The records span
// SPLAT_BLOCKS bindings of SPLATS_PER_BLOCK each, so a large scene never exceeds the
// per-block storage limit.
#include "splat.glsl"

layout(std430, binding = 0) readonly buffer Order { uint order[]; };
// Block k, at binding k + 1, holds the records from k * SPLATS_PER_BLOCK on. The blocks
// beyond the first are declared and read through one list: SPLAT_BLOCKS_n(X) applies
// X(k, binding, block name, array) to blocks 1 .. n - 1, k as the uint literal
// fetch_splat compares. Each binding is spelt out, not computed: a layout binding must
// be a literal in GLSL 4.30.
#if SPLAT_BLOCKS < 1 || SPLAT_BLOCKS > 8
#error SPLAT_BLOCKS must be 1 to 8 (render/gl/storage.py, MAX_SPLAT_BLOCKS)
#endif
#define SPLAT_BLOCKS_1(X)
#define SPLAT_BLOCKS_2(X) SPLAT_BLOCKS_1(X) X(1u, 2, Splats1, splats1)
#define SPLAT_BLOCKS_3(X) SPLAT_BLOCKS_2(X) X(2u, 3, Splats2, splats2)
#define SPLAT_BLOCKS_4(X) SPLAT_BLOCKS_3(X) X(3u, 4, Splats3, splats3)
#define SPLAT_BLOCKS_5(X) SPLAT_BLOCKS_4(X) X(4u, 5, Splats4, splats4)
#define SPLAT_BLOCKS_6(X) SPLAT_BLOCKS_5(X) X(5u, 6, Splats5, splats5)
#define SPLAT_BLOCKS_7(X) SPLAT_BLOCKS_6(X) X(6u, 7, Splats6, splats6)
#define SPLAT_BLOCKS_8(X) SPLAT_BLOCKS_7(X) X(7u, 8, Splats7, splats7)
#define PASTE(a, b) a##b
#define PASTE_EXPANDED(a, b) PASTE(a, b)  // SPLAT_BLOCKS is expanded before it is pasted
#define FOR_EACH_EXTRA_SPLAT_BLOCK(X) PASTE_EXPANDED(SPLAT_BLOCKS_, SPLAT_BLOCKS)(X)

#define DECLARE_SPLAT_BLOCK(k, at, Block, records) layout(std430, binding = at) readonly buffer Block { Splat records[]; };
DECLARE_SPLAT_BLOCK(0u, 1, Splats0, splats0)
FOR_EACH_EXTRA_SPLAT_BLOCK(DECLARE_SPLAT_BLOCK)

uniform uint u_order_count;

Splat fetch_splat(uint index) {
    uint block = index / uint(SPLATS_PER_BLOCK);
    uint i = index - block * uint(SPLATS_PER_BLOCK);
#define FETCH_FROM_SPLAT_BLOCK(k, at, Block, records) if (block == k) return records[i];
    FOR_EACH_EXTRA_SPLAT_BLOCK(FETCH_FROM_SPLAT_BLOCK)
    return splats0[i];
}

#ifndef SPLATS_ONLY  // the vertex stages'; fragment and compute stages read records by index only
// The order is back to front; the transmittance cut-off and the per-pixel order
// draw it front to back (so gl_InstanceID is the rank in the front-to-back order).
uint this_instance_index() {
#if FRONT_TO_BACK || PER_PIXEL
    return order[u_order_count - 1u - uint(gl_InstanceID)];
#else
    return order[gl_InstanceID];
#endif
}

Splat this_instance_splat() {
    return fetch_splat(this_instance_index());
}

// Triangle-strip corners (-,-), (+,-), (-,+), (+,+).
vec2 quad_corner() {
    return vec2((gl_VertexID & 1) != 0 ? 1.0 : -1.0, (gl_VertexID & 2) != 0 ? 1.0 : -1.0);
}
#endif
