// The splat fragment stages' output, included first by raygs.frag and gs.frag: how a
// fragment's (rgb, alpha) enters the target (maths page, sections 5, 10 and 11).
// Default: premultiplied output, blended back to front with (ONE, ONE_MINUS_SRC_ALPHA)
// over a target cleared to (background, 0).
// FRONT_TO_BACK (the transmittance cut-off of INRIA and GOF): the shader reads the
// target itself (framebuffer fetch, blending off); the target holds the premultiplied
// colour so far and 1 - T, and a pixel whose cut-off fired is marked by alpha - 2
// (below -1), after which every later fragment is skipped, as INRIA's loop stops.
// The resolve pass adds the background and removes the mark.
// GEOMETRY (the geometry outputs of a global order without the cut-off,
// render/gl/geometry.py): two more attachments blended exactly as colour is, so they
// hold sum T alpha z and sum T alpha n: (z alpha, 0, 0, alpha) and (n alpha, alpha), the
// alpha there only for the blend factor.
// PER_PIXEL 1 (fragment lists, fragment_lists.glsl): no colour output; the fragment
// is counted, or stored with its t* in its pixel's list. PER_PIXEL 2 (a k-buffer,
// kbuffer.glsl): the fragment enters its pixel's window of K, through framebuffer fetch.
// WEIGHTS (render/gl/weighing.py), front to back: each fragment's weight T alpha raises
// its gaussian's in a storage buffer (the fragment lists' resolve does it for them).
// Included first: an #extension directive must precede all other code.
#if FRONT_TO_BACK || PER_PIXEL == 2
#extension GL_EXT_shader_framebuffer_fetch : require
#endif
#include "features.glsl"

uniform float u_p_min;

#if PER_PIXEL
flat in uint v_index;
flat in uint v_rank;
#elif WEIGHTS && FRONT_TO_BACK
// Each fragment of the pixels weighed raises its gaussian's weight to T alpha
// (render/gl/weighing.py: the global order's weights through framebuffer fetch).
flat in uint v_index;
layout(std430, binding = 16) buffer Weights { uint weights[]; };
uniform sampler2D u_inside;  // the pixels weighed (> 0.5), in the target's pixels
#endif
#if PER_PIXEL == 1
#include "fragment_lists.glsl"
uniform int u_pass;  // 0: count the kept fragments of each pixel; 1: store those of u_part

void store_fragment(vec3 rgb, float alpha, float t) {
    ivec2 p = ivec2(gl_FragCoord.xy);
    uint i = pixel_index(p);
    if (u_pass == 0) {
        atomicAdd(counts[i], 1u);
        return;
    }
    if (!in_part(p)) return;  // the scissor already keeps the part; this keeps the pool safe
    uint slot = atomicAdd(cursors[i], 1u);
    if (slot >= list_start(p) + counts[i]) {  // never: the count pass kept the same fragments
        atomicAdd(status[0], 1u);
        return;
    }
    pool[slot] = uvec4(floatBitsToUint(t), floatBitsToUint(alpha), v_index, v_rank);
}
#elif PER_PIXEL == 2
#include "kbuffer.glsl"
#elif FRONT_TO_BACK
#if GEOMETRY
#error the geometry outputs of the cut-off go through the fragment lists
#endif
inout vec4 frag_color;
#elif GEOMETRY
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 geometry_depth;
layout(location = 2) out vec4 geometry_normal;
#else
out vec4 frag_color;
#endif

// t: the ray parameter of the gaussian's peak on this pixel's unit ray (per-pixel order
// only); z, normal: the fragment's depth and normal (GEOMETRY only).
void emit_geometry(vec3 rgb, float alpha, float t, float z, vec3 normal) {
    if (alpha < u_p_min) discard;
    if (ALPHA_CLAMP) alpha = min(alpha, ALPHA_MAX);
#if PER_PIXEL
    store_fragment(rgb, alpha, t);
#elif FRONT_TO_BACK
    vec4 so_far = frag_color;
    if (so_far.a < -0.5) discard;
    float transmittance = 1.0 - so_far.a;
    float next = transmittance * (1.0 - alpha);
    if (CUTOFF && next < MIN_TRANSMITTANCE) {
        frag_color = vec4(so_far.rgb, so_far.a - 2.0);
        return;
    }
#if WEIGHTS
    if (texelFetch(u_inside, ivec2(gl_FragCoord.xy), 0).r > 0.5) {
        atomicMax(weights[v_index], floatBitsToUint(transmittance * alpha));
    }
#endif
    frag_color = vec4(so_far.rgb + transmittance * alpha * rgb, 1.0 - next);
#else
    frag_color = vec4(rgb * alpha, alpha);
#if GEOMETRY
    geometry_depth = vec4(z * alpha, 0.0, 0.0, alpha);
    geometry_normal = vec4(normal * alpha, alpha);
#endif
#endif
}

void emit_at(vec3 rgb, float alpha, float t) {
    emit_geometry(rgb, alpha, t, 0.0, vec3(0.0));
}

void emit(vec3 rgb, float alpha) {
    emit_at(rgb, alpha, 0.0);
}
