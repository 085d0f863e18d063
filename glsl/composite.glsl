// How a fragment's (rgb, alpha) enters the target (maths page, sections 5 and 10).
// Default: premultiplied output, blended back to front with (ONE, ONE_MINUS_SRC_ALPHA)
// over a target cleared to (background, 0).
// FRONT_TO_BACK (the transmittance cut-off of INRIA and GOF): the shader reads the
// target itself (framebuffer fetch, blending off); the target holds the premultiplied
// colour so far and 1 - T, and a pixel whose cut-off fired is marked by alpha - 2
// (below -1), after which every later fragment is skipped, as INRIA's loop stops.
// The resolve pass adds the background and removes the mark.
// Included first: an #extension directive must precede all other code.
#if FRONT_TO_BACK
#extension GL_EXT_shader_framebuffer_fetch : require
#endif
#include "features.glsl"

uniform float u_p_min;

#if FRONT_TO_BACK
inout vec4 frag_color;
#else
out vec4 frag_color;
#endif

void emit(vec3 rgb, float alpha) {
    if (alpha < u_p_min) discard;
    if (ALPHA_CLAMP) alpha = min(alpha, ALPHA_MAX);
#if FRONT_TO_BACK
    vec4 so_far = frag_color;
    if (so_far.a < -0.5) discard;
    float transmittance = 1.0 - so_far.a;
    float next = transmittance * (1.0 - alpha);
    if (next < MIN_TRANSMITTANCE) {
        frag_color = vec4(so_far.rgb, so_far.a - 2.0);
        return;
    }
    frag_color = vec4(so_far.rgb + transmittance * alpha * rgb, 1.0 - next);
#else
    frag_color = vec4(rgb * alpha, alpha);
#endif
}
