// Fragment lists, after a part's fill pass: each pixel sorts its list in place in the
// pool and composites it front to back (per_pixel_composite.glsl), then stores (RGB over the
// background, accumulated alpha) in u_output. u_window 0: the exact order, ascending
// (t*, scene index). u_window K: the k-buffer's result, the list sorted by arrival
// (rank in the global front-to-back order) and streamed through a window of K.
// Lists arrive nearly sorted: insertion sort up to INSERTION_MAX entries, heapsort
// beyond (no fixed-size array caps a pixel's fragments).
#define SPLATS_ONLY 1
#include "splat_blocks.glsl"
#include "fragment_lists.glsl"
#include "per_pixel_composite.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f, binding = 0) uniform writeonly image2D u_output;
uniform vec3 u_background;
uniform int u_window;

const uint INSERTION_MAX = 64u;

bool precedes(uvec4 a, uvec4 b) {
    if (u_window == 0) return comes_first(uintBitsToFloat(a.x), a.z, uintBitsToFloat(b.x), b.z);
    return a.w < b.w;
}

void sift_down(uint start, uint root, uint end) {  // a max-heap of pool[start .. start + end)
    while (true) {
        uint child = 2u * root + 1u;
        if (child >= end) return;
        if (child + 1u < end && precedes(pool[start + child], pool[start + child + 1u])) child += 1u;
        uvec4 top = pool[start + root], below = pool[start + child];
        if (!precedes(top, below)) return;
        pool[start + root] = below;
        pool[start + child] = top;
        root = child;
    }
}

void sort_list(uint start, uint n) {
    if (n <= INSERTION_MAX) {
        for (uint j = 1u; j < n; ++j) {
            uvec4 key = pool[start + j];
            uint i = j;
            while (i > 0u && precedes(key, pool[start + i - 1u])) {
                pool[start + i] = pool[start + i - 1u];
                --i;
            }
            pool[start + i] = key;
        }
        return;
    }
    for (uint r = n / 2u; r > 0u; --r) sift_down(start, r - 1u, n);
    for (uint end = n - 1u; end > 0u; --end) {
        uvec4 top = pool[start];
        pool[start] = pool[start + end];
        pool[start + end] = top;
        sift_down(start, 0u, end);
    }
}

vec3 color_of(uvec4 entry) {
    return fetch_splat(entry.z).color.rgb;
}

bool entry_first(uvec4 a, uvec4 b) {
    return comes_first(uintBitsToFloat(a.x), a.z, uintBitsToFloat(b.x), b.z);
}

void main() {
    ivec2 p = u_part.xy + ivec2(gl_GlobalInvocationID.xy);
    if (!in_part(p)) return;
    uint i = pixel_index(p);
    uint start = list_start(p), n = counts[i];
    if (cursors[i] != start + n) atomicAdd(status[1], 1u);
    sort_list(start, n);
    vec4 state = vec4(0.0);
    if (u_window == 0) {
        for (uint j = 0u; j < n; ++j) {
            uvec4 entry = pool[start + j];
            composite_fragment(state, color_of(entry), uintBitsToFloat(entry.y));
        }
    } else {
        uvec4 window[MAX_ORDER_K];
        int held = 0;
        for (uint j = 0u; j < n; ++j) {
            uvec4 entry = pool[start + j];
            if (held < u_window) {
                window[held++] = entry;
                continue;
            }
            int first = 0;
            for (int k = 1; k < held; ++k) if (entry_first(window[k], window[first])) first = k;
            if (entry_first(entry, window[first])) {
                composite_fragment(state, color_of(entry), uintBitsToFloat(entry.y));
            } else {
                composite_fragment(state, color_of(window[first]), uintBitsToFloat(window[first].y));
                window[first] = entry;
            }
        }
        for (int j = 1; j < held; ++j) {
            uvec4 key = window[j];
            int k = j - 1;
            while (k >= 0 && entry_first(key, window[k])) {
                window[k + 1] = window[k];
                --k;
            }
            window[k + 1] = key;
        }
        for (int j = 0; j < held; ++j) composite_fragment(state, color_of(window[j]), uintBitsToFloat(window[j].y));
    }
    imageStore(u_output, p, finish_pixel(state, u_background));
}
