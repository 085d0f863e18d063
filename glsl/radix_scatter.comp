// Radix sort, each pass last: each workgroup sorts its tile by the pass's digit in shared
// memory, stably, and writes each element to its (digit, tile) start plus its place among
// the tile's elements of that digit.
//
// Stability without relying on scheduling: the local sort ranks 4 bits at a time
// (least significant first, so two steps make an 8-bit digit). Each invocation owns
// TILE_ITEMS consecutive elements and counts their 16 possible values in order, in
// registers, two 16-bit counters to a word; one exclusive scan over all invocations'
// counters in (value, invocation) order then gives every element the number of elements
// before it with a smaller value, or with the same value and a smaller index. Every step
// is a sum, the same whichever invocation runs first.
#include "radix.glsl"
#include "radix_block_scan.glsl"

layout(local_size_x = WORKGROUP) in;
layout(std430, binding = 2) readonly buffer KeysIn { uint keys_in[]; };
layout(std430, binding = 3) readonly buffer ValuesIn { uint values_in[]; };
layout(std430, binding = 4) writeonly buffer KeysOut { uint keys_out[]; };
layout(std430, binding = 5) writeonly buffer ValuesOut { uint values_out[]; };
layout(std430, binding = 6) readonly buffer Counts { uint counts[]; };
layout(std430, binding = 7) readonly buffer BlockSums { uint block_sums[]; };
uniform uint u_shift;

#define COUNTER_WORDS 8u  // 16 values in 16-bit halves: value v in word v % 8, half v / 8

shared uint s_keys[TILE];
shared uint s_values[TILE];
// Invocation t's word w at w * WORKGROUP + t: read as one array, the words run
// value-major, invocation-minor, the order the ranks need.
shared uint s_counters[COUNTER_WORDS * uint(WORKGROUP)];
shared uint s_start[RADIX];  // where each digit starts in the sorted tile
shared uint s_base[RADIX];   // where the tile's elements of each digit start in the output

uint digit(uint key) {
    return (key >> u_shift) & (RADIX - 1u);
}

void main() {
    uint t = gl_LocalInvocationIndex;
    uint tile = group_index();
    bool live = tile < params.tiles;  // not so for a folded dispatch's surplus groups
    uint first = tile * TILE;
    uint n = live ? min(TILE, params.count - first) : 0u;

    // Loaded in stripes (neighbouring invocations, neighbouring words), ranked in runs of
    // TILE_ITEMS per invocation. The tile's last one pads with all-ones keys: their digit
    // is the largest and they come last, so they sort to places >= n, never written.
    for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
        uint j = i * uint(WORKGROUP) + t;
        bool real = j < n;
        s_keys[j] = real ? keys_in[first + j] : 0xFFFFFFFFu;
        s_values[j] = real ? values_in[first + j] : 0u;
    }
    if (live) {
        for (uint d = t; d < RADIX; d += uint(WORKGROUP)) {
            uint at = d * params.tiles + tile;
            s_base[d] = counts[at] + block_sums[at / SCAN_BLOCK];
        }
    }
    sync_shared();

    uint keys[TILE_ITEMS], values[TILE_ITEMS], ranks[TILE_ITEMS];
    for (uint low = 0u; low < uint(DIGIT_BITS); low += 4u) {
        for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
            keys[i] = s_keys[t * uint(TILE_ITEMS) + i];
            values[i] = s_values[t * uint(TILE_ITEMS) + i];
        }
        // Selects, not c[v & 7u]: a register array indexed by data would live in memory.
        uint c[COUNTER_WORDS];
        for (uint w = 0u; w < COUNTER_WORDS; ++w) c[w] = 0u;
        for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
            uint v = (digit(keys[i]) >> low) & 15u;
            uint half_shift = (v >> 3u) * 16u;
            uint held = 0u;
            for (uint w = 0u; w < COUNTER_WORDS; ++w) {
                bool hit = w == (v & 7u);
                held = hit ? c[w] : held;
                c[w] += hit ? 1u << half_shift : 0u;
            }
            ranks[i] = (held >> half_shift) & 0xFFFFu;
        }
        for (uint w = 0u; w < COUNTER_WORDS; ++w) s_counters[w * uint(WORKGROUP) + t] = c[w];
        sync_shared();
        // Scanned in runs of COUNTER_WORDS consecutive words per invocation. A 16-bit half
        // never carries into the next: a tile holds fewer than 65536 elements.
        uint sum = 0u;
        for (uint w = 0u; w < COUNTER_WORDS; ++w) sum += s_counters[t * COUNTER_WORDS + w];
        uint total;
        uint prefix = workgroup_exclusive_scan(sum, total);
        for (uint w = 0u; w < COUNTER_WORDS; ++w) {
            uint words = s_counters[t * COUNTER_WORDS + w];
            s_counters[t * COUNTER_WORDS + w] = prefix;
            prefix += words;
        }
        sync_shared();
        // The high halves (values 8..15) were summed apart from the low ones: they come
        // after all elements of values 0..7, the low half of the total.
        uint below_high = total & 0xFFFFu;
        for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
            uint v = (digit(keys[i]) >> low) & 15u;
            uint half_shift = (v >> 3u) * 16u;
            uint before = s_counters[(v & 7u) * uint(WORKGROUP) + t];
            uint to = ((before >> half_shift) & 0xFFFFu) + (v >= 8u ? below_high : 0u) + ranks[i];
            s_keys[to] = keys[i];
            s_values[to] = values[i];
        }
        sync_shared();
    }

    // The sorted tile's runs: a digit starts where the element before has another.
    for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
        uint p = i * uint(WORKGROUP) + t;
        uint d = digit(s_keys[p]);
        if (p == 0u || digit(s_keys[p - 1u]) != d) s_start[d] = p;
    }
    sync_shared();
    for (uint i = 0u; i < uint(TILE_ITEMS); ++i) {
        uint p = i * uint(WORKGROUP) + t;
        if (p < n) {
            uint key = s_keys[p];
            uint to = s_base[digit(key)] + p - s_start[digit(key)];
            keys_out[to] = key;
            values_out[to] = s_values[p];
        }
    }
}
