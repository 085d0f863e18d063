// The GPU radix sort's shared definitions (raygs_viewer/render/gl/radix_sort.py): the
// layout of its passes, the parameters the setup pass derives from the element count,
// and the workgroup helpers. Every pass reads the count from RadixParams, never from a
// uniform, so that a count written by an earlier GPU pass needs no trip to the host.

#ifndef WORKGROUP
#define WORKGROUP 256      // invocations per workgroup; GL guarantees 1024
#endif
#ifndef DIGIT_BITS
#define DIGIT_BITS 8       // bits sorted per pass: 4 or 8
#endif
#ifndef TILE_ITEMS
#define TILE_ITEMS 8       // elements per invocation in the count and scatter passes
#endif
#ifndef SCAN_ITEMS
#define SCAN_ITEMS 8       // entries per invocation in the scan passes
#endif
#ifndef MAX_GROUPS_X
#define MAX_GROUPS_X 65535u  // GL's guaranteed workgroups per dimension; more fold into y
#endif

#define RADIX (1u << DIGIT_BITS)
#define TILE (uint(WORKGROUP) * uint(TILE_ITEMS))
#define SCAN_BLOCK (uint(WORKGROUP) * uint(SCAN_ITEMS))

// Written by radix_setup.comp; the two uvec4 are also the indirect dispatch arguments
// (x, y, 1, padding) of the tile passes and of the block scan.
layout(std430, binding = 0) buffer RadixParams {
    uint count;        // elements to sort
    uint tiles;        // ceil(count / TILE)
    uint scan_n;       // RADIX * tiles: the (digit, tile) counts
    uint scan_blocks;  // ceil(scan_n / SCAN_BLOCK)
    uvec4 tile_groups;
    uvec4 scan_groups;
} params;

// The workgroup's index in a dispatch folded into x and y (see fold_groups).
uint group_index() {
    return gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
}

// Barriers stand in loops and helpers whose control flow is the same for the whole
// workgroup (bounds from constants or RadixParams), and no pass returns early before one:
// the surplus groups of a folded dispatch run through with nothing to do.

// Shared memory written before a barrier is read after it: barrier() orders shared
// memory for compute shaders by the letter of the spec; memoryBarrierShared() too makes
// it hold on drivers that read the spec more narrowly.
void sync_shared() {
    memoryBarrierShared();
    barrier();
}
