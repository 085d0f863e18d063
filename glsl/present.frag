// Shows the float render target 1:1. The texel comes from the interpolated uv, not
// from gl_FragCoord: Mesa 22's llvmpipe sometimes keeps the window's flipped
// gl_FragCoord convention for the first draw into a texture after a swap.
// Its RGB is already composited over the background, so alpha is dropped.
uniform sampler2D u_image;
in vec2 v_uv;
out vec4 out_color;

void main() {
    ivec2 size = textureSize(u_image, 0);
    ivec2 texel = clamp(ivec2(floor(v_uv * vec2(size))), ivec2(0), size - 1);
    out_color = vec4(clamp(texelFetch(u_image, texel, 0).rgb, 0.0, 1.0), 1.0);
}
