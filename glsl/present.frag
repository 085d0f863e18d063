// Shows the float render target 1:1 (texelFetch: no filtering, no half-pixel shift).
// Its RGB is already composited over the background, so alpha is dropped.
uniform sampler2D u_image;
uniform ivec2 u_origin;   // lower-left corner of the viewport, window pixels
out vec4 out_color;

void main() {
    out_color = vec4(clamp(texelFetch(u_image, ivec2(gl_FragCoord.xy) - u_origin, 0).rgb, 0.0, 1.0), 1.0);
}
