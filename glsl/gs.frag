#include "fragment_output.glsl"
// The projected 2D gaussian at the pixel centre (the offset is exact there: the quad
// is drawn in image space with w = 1, so interpolation is linear).
in vec2 v_offset;
flat in vec4 v_conic_opacity;
flat in vec3 v_color;

void main() {
    vec2 d = v_offset;
    vec3 conic = v_conic_opacity.xyz;
    float power = conic.x * d.x * d.x + 2.0 * conic.y * d.x * d.y + conic.z * d.y * d.y;
    emit(v_color, v_conic_opacity.w * exp(-0.5 * power));
}
