// Fragment lists, after the count pass: each row's exclusive prefix sums of its pixels'
// counts (row_offsets), and the row's total, most at one pixel and covered pixels,
// which the host reads back to cut the image into parts that fit the pool.
#include "fragment_lists.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = 15) buffer RowStats { uvec4 row_stats[]; };
uniform int u_height;

void main() {
    int y = int(gl_GlobalInvocationID.x);
    if (y >= u_height) return;
    uint total = 0u, most = 0u, covered = 0u;
    for (int x = 0; x < u_width; ++x) {
        uint i = pixel_index(ivec2(x, y));
        uint n = counts[i];
        row_offsets[i] = total;
        total += n;
        most = max(most, n);
        covered += n > 0u ? 1u : 0u;
    }
    row_stats[y] = uvec4(total, most, covered, 0u);
}
