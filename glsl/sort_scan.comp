// GPU sort, second pass: where each workgroup's kept entries start in the compacted
// order (an exclusive prefix sum of the cull's group counts, in place), and their total,
// by one workgroup that walks the counts with a running carry (SCAN_ITEMS * WORKGROUP a
// step: 2 steps for 33M entries). A sum in a fixed order: no atomics decide a place.
#include "sort_common.glsl"
#include "radix_block_scan.glsl"

layout(local_size_x = WORKGROUP) in;
layout(std430, binding = 5) buffer GroupCounts { uint group_counts[]; };

uniform uint u_groups;  // the cull's workgroups

void main() {
    uint t = gl_LocalInvocationIndex;
    uint carry = 0u;
    for (uint first = 0u; first < u_groups; first += uint(WORKGROUP) * uint(SCAN_ITEMS)) {
        uint base = first + t * uint(SCAN_ITEMS);
        uint sum = 0u;
        for (uint i = 0u; i < uint(SCAN_ITEMS); ++i) {
            if (base + i < u_groups) sum += group_counts[base + i];
        }
        uint total;
        uint start = carry + workgroup_exclusive_scan(sum, total);
        for (uint i = 0u; i < uint(SCAN_ITEMS); ++i) {
            if (base + i < u_groups) {
                uint count = group_counts[base + i];
                group_counts[base + i] = start;
                start += count;
            }
        }
        carry += total;
    }
    if (t == 0u) summary.visible = carry;
}
