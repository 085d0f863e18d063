// The GPU depth sort's shared definitions (raygs_viewer/render/gl/gpu_sort.py): its
// layout, the bindings of its passes and the exact float32 arithmetic they repeat from
// the CPU sort (raygs_viewer/sort/cull.py, keys.py), bit for bit.
//
// Exactness: every float32 product and sum that the CPU rounds on its own is written
// into a ``precise`` variable (GLSL may otherwise fuse a product and a sum into one
// FMA, or reorder a sum), in the CPU's order of operations; GLSL rounds +, - and *
// correctly. A square root is not correctly rounded in GLSL (NVIDIA's is an
// approximation), so sqrt_rn corrects it with exact double arithmetic. The constants
// the CPU computes in float64 and rounds to float32 (the plane coefficients, the slack,
// the quantisation scale) come from the host as float32 bits, never recomputed here.

#ifndef WORKGROUP
#define WORKGROUP 256    // invocations per workgroup
#endif
#ifndef TILE_ITEMS
#define TILE_ITEMS 8     // list entries per invocation in the cull and compaction passes
#endif
#ifndef SCAN_ITEMS
#define SCAN_ITEMS 8     // group counts per invocation and step in the scan pass
#endif

#define TILE (uint(WORKGROUP) * uint(TILE_ITEMS))
#define NO_ROW 0xFFFFFFFFu  // a list entry the cull dropped

// Counts and ranges of the cull, read back by the host (one small read per sort). The
// ranges are float32 as ordered_bits: min and max of those are the floats' min and max,
// exactly, whatever order the atomics land in.
layout(std430, binding = 6) buffer Summary {
    uint visible;        // kept list entries (the scan pass writes it)
    uint depth_low;      // ordered_bits of the least and greatest depth kept
    uint depth_high;
    uint distance_low;   // ... of the least and greatest distance of a candidate
    uint distance_high;
} summary;

// Shared memory written before a barrier is read after it (see radix.glsl).
void sync_shared() {
    memoryBarrierShared();
    barrier();
}

// A float32's bits as a uint that orders like the float (NaN excluded): -inf lowest, -0
// just below +0 (gpu_sort.py's float_of_ordered is the inverse).
uint ordered(uint bits) {
    return (bits & 0x80000000u) != 0u ? ~bits : bits | 0x80000000u;
}

uint ordered_bits(float value) {
    return ordered(floatBitsToUint(value));
}

bool is_nan(float value) {  // on the bits: a compiler assuming no NaNs cannot drop it
    return (floatBitsToUint(value) & 0x7FFFFFFFu) > 0x7F800000u;
}
