// The ray's divergence from the quad coordinate (maths page, section 5, Eq. 16),
// premultiplied output for back-to-front (ONE, ONE_MINUS_SRC_ALPHA) blending.
in vec2 v_plane;
flat in vec4 v_color_opacity;
flat in float v_c2;

uniform float u_p_min;

out vec4 frag_color;

void main() {
    float r2 = dot(v_plane, v_plane);
    float divergence = r2 / (1.0 + r2 / v_c2);
    float alpha = v_color_opacity.a * exp(-0.5 * divergence);
    if (alpha < u_p_min) discard;
    frag_color = vec4(v_color_opacity.rgb * alpha, alpha);
}
