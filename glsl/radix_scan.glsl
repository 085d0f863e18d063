// The scan passes' common step: an exclusive prefix sum of SCAN_BLOCK values held in
// shared memory (loaded in a coalesced order by the caller), each invocation summing
// SCAN_ITEMS consecutive ones serially around one workgroup scan.
#include "radix_block_scan.glsl"

shared uint s_block[SCAN_BLOCK];

// Replaces s_block by its exclusive prefix sums plus ``carry``; returns the block's sum.
uint scan_shared_block(uint carry) {
    uint t = gl_LocalInvocationIndex;
    uint sum = 0u;
    for (uint i = 0u; i < uint(SCAN_ITEMS); ++i) sum += s_block[t * uint(SCAN_ITEMS) + i];
    uint total;
    uint prefix = carry + workgroup_exclusive_scan(sum, total);
    for (uint i = 0u; i < uint(SCAN_ITEMS); ++i) {
        uint v = s_block[t * uint(SCAN_ITEMS) + i];
        s_block[t * uint(SCAN_ITEMS) + i] = prefix;
        prefix += v;
    }
    sync_shared();
    return total;
}
