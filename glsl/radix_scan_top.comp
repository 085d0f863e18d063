// Radix sort, each pass third: the exclusive scan of the block sums, by one workgroup that
// walks them SCAN_BLOCK at a time with a running carry. There are RADIX * M / (TILE *
// SCAN_BLOCK) of them (489 for 8M elements in the default layout): one step up to 33M.
// The loop's bound comes from the buffer, the same for every invocation, so its barriers
// stay in uniform control flow.
#include "radix.glsl"
#include "radix_scan.glsl"

layout(local_size_x = WORKGROUP) in;
layout(std430, binding = 7) buffer BlockSums { uint block_sums[]; };

void main() {
    uint t = gl_LocalInvocationIndex;
    uint n = params.scan_blocks;
    uint carry = 0u;
    for (uint first = 0u; first < n; first += SCAN_BLOCK) {
        for (uint i = 0u; i < uint(SCAN_ITEMS); ++i) {
            uint j = i * uint(WORKGROUP) + t;
            s_block[j] = first + j < n ? block_sums[first + j] : 0u;
        }
        sync_shared();
        uint total = scan_shared_block(carry);
        for (uint i = 0u; i < uint(SCAN_ITEMS); ++i) {
            uint j = i * uint(WORKGROUP) + t;
            if (first + j < n) block_sums[first + j] = s_block[j];
        }
        carry += total;
        sync_shared();  // the next step overwrites s_block
    }
}
