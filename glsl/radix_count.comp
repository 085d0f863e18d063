// Radix sort, each pass first: the digit histogram of each tile, stored digit-major
// (counts[digit * tiles + tile]) so that one exclusive scan of the array gives each
// (digit, tile) the place where its elements start in the output.
// The atomics only count: a sum does not depend on the order they land in.
#include "radix.glsl"

layout(local_size_x = WORKGROUP) in;
layout(std430, binding = 2) readonly buffer KeysIn { uint keys_in[]; };
layout(std430, binding = 6) writeonly buffer Counts { uint counts[]; };
uniform uint u_shift;  // the pass's digit: bits u_shift .. u_shift + DIGIT_BITS - 1

shared uint s_histogram[RADIX];

void main() {
    uint t = gl_LocalInvocationIndex;
    uint tile = group_index();
    bool live = tile < params.tiles;  // not so for a folded dispatch's surplus groups
    uint first = tile * TILE;
    uint n = live ? min(TILE, params.count - first) : 0u;
    for (uint d = t; d < RADIX; d += uint(WORKGROUP)) s_histogram[d] = 0u;
    sync_shared();
    for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
        uint j = i * uint(WORKGROUP) + t;
        if (j < n) atomicAdd(s_histogram[(keys_in[first + j] >> u_shift) & (RADIX - 1u)], 1u);
    }
    sync_shared();
    if (live) {
        for (uint d = t; d < RADIX; d += uint(WORKGROUP)) counts[d * params.tiles + tile] = s_histogram[d];
    }
}
