// The bounded per-pixel order as a k-buffer in colour attachments, read and written
// through framebuffer fetch (maths page, section 11; render/gl/kbuffer.py). The
// fragments arrive front to back in the global order; attachment 0 holds the composite
// state (per_pixel_composite.glsl), attachments 1..ORDER_K the window, each entry
// vec4(t*, alpha, scene index, 0), empty while alpha is 0 (a kept fragment has
// alpha >= p_min > 0). The first entry's w counts the pixel's fragments (statistics).
// When a fragment arrives and the window is full, the first by (t*, index) of the
// K + 1 is composited and leaves; kbuffer_resolve.comp composites what remains.
#define SPLATS_ONLY 1
#include "splat_blocks.glsl"
#include "per_pixel_composite.glsl"

layout(location = 0) inout vec4 kb_state;
// Arrays of at least two: Mesa 22 (llvmpipe) miscompiles arrays of one here; with K = 1
// the second entry has no attachment and is never used.
#define KB_SLOTS (ORDER_K > 1 ? ORDER_K : 2)
layout(location = 1) inout vec4 kb_entries[KB_SLOTS];

void store_fragment(vec3 rgb, float alpha, float t) {
    vec4 e[KB_SLOTS];
    for (int k = 0; k < ORDER_K; ++k) e[k] = kb_entries[k];
    float seen = e[0].w + 1.0;
    if (kb_state.a >= -0.5) {
        int empty = -1, first = -1;
        for (int k = 0; k < ORDER_K; ++k) {
            if (e[k].y == 0.0) {
                if (empty < 0) empty = k;
            } else if (first < 0 || comes_first(e[k].x, uint(e[k].z), e[first].x, uint(e[first].z))) {
                first = k;
            }
        }
        vec4 entry = vec4(t, alpha, float(v_index), 0.0);
        if (empty >= 0) {
            e[empty] = entry;
        } else if (comes_first(t, v_index, e[first].x, uint(e[first].z))) {
            composite_fragment(kb_state, rgb, alpha);
        } else {
            composite_fragment(kb_state, fetch_splat(uint(e[first].z)).color.rgb, e[first].y);
            e[first] = entry;
        }
    }
    e[0].w = seen;
    for (int k = 0; k < ORDER_K; ++k) kb_entries[k] = e[k];
}
