// The per-pixel order's compositing (maths page, section 11), shared by the fragment
// lists' resolve, the k-buffer's fragments and its resolve.
// A fragment is (t*, alpha, scene index); the exact order is ascending (t*, index).
// The composite state is vec4(premultiplied colour so far, 1 - T); with the
// transmittance cut-off (CUTOFF) a pixel whose cut-off fired is marked by alpha - 2,
// and every later fragment is skipped (INRIA's rule: the fragment that would take T
// below MIN_TRANSMITTANCE ends the pixel, itself not drawn).
bool comes_first(float t_a, uint index_a, float t_b, uint index_b) {
    return t_a < t_b || (t_a == t_b && index_a < index_b);
}

// Returns the fragment's weight T alpha, or -1 where it was not composited (the pixel
// had ended, or it ends it): the geometry outputs weigh by it.
float composite_fragment(inout vec4 state, vec3 rgb, float alpha) {
    if (state.a < -0.5) return -1.0;
    float transmittance = 1.0 - state.a;
    float next = transmittance * (1.0 - alpha);
    if (CUTOFF && next < MIN_TRANSMITTANCE) {
        state.a -= 2.0;
        return -1.0;
    }
    float weight = transmittance * alpha;
    state = vec4(state.rgb + weight * rgb, 1.0 - next);
    return weight;
}

// RGB over the background, A = accumulated alpha.
vec4 finish_pixel(vec4 state, vec3 background) {
    float alpha = state.a < -0.5 ? state.a + 2.0 : state.a;
    return vec4(state.rgb + (1.0 - alpha) * background, alpha);
}
