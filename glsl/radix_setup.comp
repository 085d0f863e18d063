// Radix sort, first: the element count, read where an earlier pass (or the host) left it,
// and what follows from it: the tiles, the scan's length and the indirect dispatch
// arguments of the passes after, so that the count never travels to the host.
#include "radix.glsl"

layout(local_size_x = 1) in;
layout(std430, binding = 1) readonly buffer CountSource { uint count_source[]; };
uniform uint u_count_word;  // the count's index in CountSource
uniform uint u_capacity;    // elements the bound key and value ranges hold

// n workgroups as (x, y, 1): y rows of at most MAX_GROUPS_X; the last row's surplus
// groups find group_index() >= n and do nothing.
uvec4 fold_groups(uint n) {
    uint x = min(n, MAX_GROUPS_X);
    return uvec4(x, x == 0u ? 0u : (n + x - 1u) / x, 1u, 0u);
}

void main() {
    // A count past the buffers would write out of bounds: the sort takes what they hold.
    uint count = min(count_source[u_count_word], u_capacity);
    uint tiles = (count + TILE - 1u) / TILE;
    uint scan_n = RADIX * tiles;
    uint scan_blocks = (scan_n + SCAN_BLOCK - 1u) / SCAN_BLOCK;
    params.count = count;
    params.tiles = tiles;
    params.scan_n = scan_n;
    params.scan_blocks = scan_blocks;
    params.tile_groups = fold_groups(tiles);
    params.scan_groups = fold_groups(scan_blocks);
}
