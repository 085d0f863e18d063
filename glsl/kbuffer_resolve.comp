// Ends the k-buffer's frame (kbuffer.glsl): composites each pixel's remaining window in
// ascending (t*, index), adds the background and stores (RGB over the background,
// accumulated alpha) in u_output; sums the statistics of the fragments seen.
#define SPLATS_ONLY 1
#include "splat_blocks.glsl"
#include "per_pixel_composite.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f, binding = 0) uniform writeonly image2D u_output;
uniform sampler2D u_state;
uniform sampler2D u_entries[ORDER_K];
uniform vec3 u_background;
// [0] fragments, [1] most at one pixel, [2] pixels with any.
layout(std430, binding = 14) buffer Stats { uint stats[]; };

shared uint s_total, s_max, s_covered;

void main() {
    if (gl_LocalInvocationIndex == 0u) {
        s_total = 0u; s_max = 0u; s_covered = 0u;
    }
    barrier();
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_output);
    if (all(lessThan(p, size))) {
        vec4 state = texelFetch(u_state, p, 0);
        vec4 e[ORDER_K];
        int n = 0;
        uint seen = 0u;
        for (int k = 0; k < ORDER_K; ++k) {
            vec4 entry = texelFetch(u_entries[k], p, 0);
            if (k == 0) seen = uint(entry.w);
            if (entry.y != 0.0) e[n++] = entry;
        }
        for (int j = 1; j < n; ++j) {  // insertion sort of at most K entries
            vec4 key = e[j];
            int i = j - 1;
            while (i >= 0 && comes_first(key.x, uint(key.z), e[i].x, uint(e[i].z))) {
                e[i + 1] = e[i];
                --i;
            }
            e[i + 1] = key;
        }
        for (int j = 0; j < n; ++j) composite_fragment(state, fetch_splat(uint(e[j].z)).color.rgb, e[j].y);
        imageStore(u_output, p, finish_pixel(state, u_background));
        if (seen > 0u) {
            atomicAdd(s_total, seen);
            atomicMax(s_max, seen);
            atomicAdd(s_covered, 1u);
        }
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u && s_covered > 0u) {
        atomicAdd(stats[0], s_total);
        atomicMax(stats[1], s_max);
        atomicAdd(stats[2], s_covered);
    }
}
