// Fragment lists, after a part's fill pass: each pixel sorts its list in place in the
// pool and composites it front to back (per_pixel_composite.glsl), then stores (RGB over the
// background, accumulated alpha) in u_output. u_window 0: the exact order, ascending
// (t*, scene index). u_window K: the k-buffer's result, the list sorted by arrival
// (rank in the global front-to-back order) and streamed through a window of K.
// u_window -1: the global order itself, by arrival (the geometry outputs of a global order).
// GEOMETRY: also (sum T alpha z, median z or 0, found, 0) in u_depth and
// (sum T alpha n, 0) in u_normal (docs/geometry.md; render/gl/geometry.py reads them).
// WEIGHTS: instead of an image, each pixel of u_inside raises weights[scene index] to
// the largest weight T alpha a gaussian has there (the float's bits, which order as the
// float for weights >= 0; render/gl/weighing.py): "select what the view shows".
// Lists arrive nearly sorted: insertion sort up to INSERTION_MAX entries, and beyond
// while it moves no more than INSERTION_MOVES_PER_ENTRY entries a fragment on average;
// heapsort otherwise (no fixed-size array caps a pixel's fragments).
#define SPLATS_ONLY 1
#include "splat_blocks.glsl"
#include "fragment_lists.glsl"
#include "per_pixel_composite.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
uniform int u_window;
#if WEIGHTS
layout(std430, binding = 16) buffer Weights { uint weights[]; };
uniform sampler2D u_inside;  // the pixels weighed (> 0.5), rows from the bottom
uniform ivec2 u_inside_origin;  // where these lists' pixels start in u_inside
#else
layout(rgba32f, binding = 0) uniform writeonly image2D u_output;
uniform vec3 u_background;
#endif
#if GEOMETRY
layout(rgba32f, binding = 1) uniform writeonly image2D u_depth;
layout(rgba32f, binding = 2) uniform writeonly image2D u_normal;
uniform vec4 u_intrinsics;  // fx, fy, cx, cy of the image's camera (sample pixels)
uniform int u_height;
vec3 g_ray;                 // this pixel's unit ray (OpenCV camera axes)
vec4 g_sums = vec4(0.0);    // sum T alpha z, sum T alpha n
vec2 g_median = vec2(0.0);  // z where the accumulated alpha first reaches 0.5, found
#endif

const uint INSERTION_MAX = 64u;
const uint INSERTION_MOVES_PER_ENTRY = 8u;

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

// Insertion sort while it stays cheap: lists arrive in the draw's order, which for the
// global order is (nearly always) their order already and for each ray's order nearly.
// Past ``budget`` moves it gives up, leaving a permutation heapsort finishes.
bool insertion_sorted(uint start, uint n, uint budget) {
    uint moves = 0u;
    for (uint j = 1u; j < n; ++j) {
        uvec4 key = pool[start + j];
        uint i = j;
        while (i > 0u && precedes(key, pool[start + i - 1u])) {
            if (++moves > budget) {
                pool[start + i] = key;
                return false;
            }
            pool[start + i] = pool[start + i - 1u];
            --i;
        }
        pool[start + i] = key;
    }
    return true;
}

void sort_list(uint start, uint n) {
    if (insertion_sorted(start, n, n <= INSERTION_MAX ? n * n : INSERTION_MOVES_PER_ENTRY * n)) return;
    for (uint r = n / 2u; r > 0u; --r) sift_down(start, r - 1u, n);
    for (uint end = n - 1u; end > 0u; --end) {
        uvec4 top = pool[start];
        pool[start] = pool[start + end];
        pool[start + end] = top;
        sift_down(start, 0u, end);
    }
}

// Composites one list entry (t* bits, alpha bits, scene index, rank) behind ``state``.
void take(inout vec4 state, uvec4 entry) {
#if WEIGHTS
    // Only the alpha matters to the transmittance: no record is read.
    float weight = composite_fragment(state, vec3(0.0), uintBitsToFloat(entry.y));
    if (weight > 0.0) atomicMax(weights[entry.z], floatBitsToUint(weight));
#else
    Splat s = fetch_splat(entry.z);
#endif
#if GEOMETRY
    float weight = composite_fragment(state, s.color.rgb, uintBitsToFloat(entry.y));
    if (weight < 0.0) return;
    // t* lies on the unit ray: its z is t* times the ray's. EWA has no t*: the centre's z.
#if MODE_GS
    float z = s.center_c2.z;
#else
    float z = uintBitsToFloat(entry.x) * g_ray.z;
#endif
    vec3 n = dot(s.normal.xyz, g_ray) > 0.0 ? -s.normal.xyz : s.normal.xyz;
    g_sums += weight * vec4(z, n);
    if (g_median.y == 0.0 && state.a >= 0.5) g_median = vec2(z, 1.0);
#elif !WEIGHTS
    composite_fragment(state, s.color.rgb, uintBitsToFloat(entry.y));
#endif
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
#if WEIGHTS
    if (texelFetch(u_inside, p + u_inside_origin, 0).r < 0.5) return;
#endif
    sort_list(start, n);
#if GEOMETRY
    // p counts rows from the bottom; the camera's v from the top.
    vec2 uv = vec2(float(p.x) + 0.5, float(u_height - 1 - p.y) + 0.5);
    g_ray = normalize(vec3((uv - u_intrinsics.zw) / u_intrinsics.xy, 1.0));
#endif
    vec4 state = vec4(0.0);
    if (u_window <= 0) {
        for (uint j = 0u; j < n; ++j) take(state, pool[start + j]);
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
                take(state, entry);
            } else {
                take(state, window[first]);
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
        for (int j = 0; j < held; ++j) take(state, window[j]);
    }
#if !WEIGHTS
    imageStore(u_output, p, finish_pixel(state, u_background));
#endif
#if GEOMETRY
    imageStore(u_depth, p, vec4(g_sums.x, g_median, 0.0));
    imageStore(u_normal, p, vec4(g_sums.yzw, 0.0));
#endif
}
