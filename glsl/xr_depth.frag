// A headset eye's depth layer (XR_KHR_composition_layer_depth): its median depth
// (render/gl/geometry.py's attachment 1: (-, median z * found, found, -)) stored as
// 1 - near / z, an infinite far plane; 1 (infinitely far) where the ray found none.
// xr/eyes.py's depth_values is its host twin, operation for operation.
uniform sampler2D u_depth;
uniform float u_near_units;  // the layer's near plane, in scene units
in vec2 v_uv;

void main() {
    ivec2 size = textureSize(u_depth, 0);
    ivec2 pixel = clamp(ivec2(floor(v_uv * vec2(size))), ivec2(0), size - 1);
    vec4 sums = texelFetch(u_depth, pixel, 0);
    float z = sums.b > 0.0 ? sums.g / sums.b : 0.0;
    gl_FragDepth = z > 0.0 ? clamp(1.0 - u_near_units / z, 0.0, 1.0) : 1.0;
}
