// GPU sort, third pass (once per key): the kept entries in scene order, each with its
// sort key, ready for the stable radix sort (radix_sort.py). Each invocation takes
// TILE_ITEMS consecutive entries; a workgroup scan of their kept counts, added to the
// group's start from the scan pass, gives each kept entry its place: the order of the
// list, so ties of the stable sort keep scene order.
//
// Keys (keys.stable_order): QUANTISED, keys.quantise's uint16 min((far - v) * scale,
// 65535) truncated (0 at far: ascending is back to front); FLOAT, the float32 order
// descending as a uint ascending (-0 as +0, NaN last, as numpy's argsort(-v)); SCENE,
// no key (the order is the compacted list itself).
#include "sort_common.glsl"
#include "radix_block_scan.glsl"

#define QUANTISED 0u
#define FLOAT 1u
#define SCENE 2u

layout(local_size_x = WORKGROUP) in;
layout(std430, binding = 0) writeonly buffer KeysOut { uint keys_out[]; };
layout(std430, binding = 1) writeonly buffer RowsOut { uint rows_out[]; };
layout(std430, binding = 3) readonly buffer Slots { uint slots[]; };
layout(std430, binding = 4) readonly buffer Values { vec2 values[]; };
layout(std430, binding = 5) readonly buffer GroupStarts { uint group_starts[]; };

uniform uint u_total;  // entries in the row list
uniform uint u_key;    // 0: depth, 1: distance
uniform uint u_mode;   // QUANTISED, FLOAT or SCENE
uniform float u_far;   // QUANTISED: the range's far end and keys.quantise_scale
uniform float u_scale;

uint sort_key(float value) {
    if (u_mode == QUANTISED) {
        precise float scaled = u_far - value;
        scaled = scaled * u_scale;
        return uint(min(scaled, 65535.0));  // truncated, as numpy's cast to uint16
    }
    if (is_nan(value)) return 0xFFFFFFFFu;
    uint bits = floatBitsToUint(value);
    // -0 and +0 are equal keys: both as +0 (on the bits, which no compiler folds away).
    if ((bits & 0x7FFFFFFFu) == 0u) bits = 0u;
    return ~ordered(bits);
}

void main() {
    uint t = gl_LocalInvocationIndex;
    uint group = gl_WorkGroupID.x;
    uint first = group * TILE + t * uint(TILE_ITEMS);
    uint kept = 0u;
    for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
        if (first + i < u_total && slots[first + i] != NO_ROW) kept++;
    }
    uint total;
    uint at = group_starts[group] + workgroup_exclusive_scan(kept, total);
    for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
        uint entry = first + i;
        if (entry >= u_total) break;
        uint row = slots[entry];
        if (row == NO_ROW) continue;
        if (u_mode != SCENE) keys_out[at] = sort_key(values[entry][u_key]);
        rows_out[at] = row;
        at++;
    }
}
