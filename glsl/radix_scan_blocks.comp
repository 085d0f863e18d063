// Radix sort, each pass second: the exclusive scan of the (digit, tile) counts, first
// level: each workgroup scans SCAN_BLOCK consecutive counts in place and leaves their sum
// in block_sums, which radix_scan_top.comp scans; the scatter adds the two.
#include "radix.glsl"
#include "radix_scan.glsl"

layout(local_size_x = WORKGROUP) in;
layout(std430, binding = 6) buffer Counts { uint counts[]; };
layout(std430, binding = 7) writeonly buffer BlockSums { uint block_sums[]; };

void main() {
    uint t = gl_LocalInvocationIndex;
    uint block = group_index();
    uint n = params.scan_n;
    uint first = block * SCAN_BLOCK;  // at or past n for a folded dispatch's surplus groups
    // Loaded and stored in stripes (neighbouring invocations, neighbouring words), scanned
    // in runs: the shared copy turns one into the other.
    for (uint i = 0u; i < uint(SCAN_ITEMS); ++i) {
        uint j = i * uint(WORKGROUP) + t;
        s_block[j] = first + j < n ? counts[first + j] : 0u;
    }
    sync_shared();
    uint total = scan_shared_block(0u);
    for (uint i = 0u; i < uint(SCAN_ITEMS); ++i) {
        uint j = i * uint(WORKGROUP) + t;
        if (first + j < n) counts[first + j] = s_block[j];
    }
    if (t == 0u && block < params.scan_blocks) block_sums[block] = total;
}
