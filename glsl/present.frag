// Shows the float render target in the viewport. The texel comes from the interpolated
// uv, not from gl_FragCoord: Mesa 22's llvmpipe sometimes keeps the window's flipped
// gl_FragCoord convention for the first draw into a texture after a swap.
// Its RGB is already composited over the background, so alpha is dropped.
//
// u_footprint is how many texels one viewport pixel covers along x and y: at most 1
// shows the nearest texel (1:1, exact); more (a stereo pair larger than the window)
// averages an even grid of up to 8 x 8 texels across the pixel, a box filter, so the
// scaled-down preview does not alias.
//
// The A/B split view: columns whose centre lies right of u_split (a fraction of the
// viewport's width, a whole number of columns) show u_right instead of u_image; both
// have the viewport's size. u_split >= 1 shows u_image alone.
uniform sampler2D u_image;
uniform sampler2D u_right;
uniform float u_split;
uniform vec2 u_footprint;
in vec2 v_uv;
out vec4 out_color;

// Clamped per texel, so that the scaled preview averages what the 1:1 view shows.
vec3 nearest(sampler2D image, ivec2 size, vec2 position) {
    return clamp(texelFetch(image, clamp(ivec2(floor(position)), ivec2(0), size - 1), 0).rgb, 0.0, 1.0);
}

void main() {
    ivec2 size = textureSize(u_image, 0);
    vec2 position = v_uv * vec2(size);
    vec3 rgb;
    if (v_uv.x >= u_split) {
        rgb = nearest(u_right, size, position);
    } else if (u_footprint.x <= 1.0 && u_footprint.y <= 1.0) {
        rgb = nearest(u_image, size, position);
    } else {
        ivec2 n = clamp(ivec2(ceil(u_footprint)), ivec2(1), ivec2(8));
        vec2 corner = position - 0.5 * u_footprint;
        rgb = vec3(0.0);
        for (int j = 0; j < n.y; ++j)
            for (int i = 0; i < n.x; ++i)
                rgb += nearest(u_image, size, corner + (vec2(i, j) + 0.5) / vec2(n) * u_footprint);
        rgb /= float(n.x * n.y);
    }
    out_color = vec4(rgb, 1.0);
}
