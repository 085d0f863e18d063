// Per-pixel fragment lists (maths page, section 11), shared by the draw's count and
// fill passes and the compute passes of render/gl/fragment_lists.py.
// Pixels are indexed y * width + x in GL's rows (y = 0 at the bottom). The image is
// drawn in parts (rectangles x0..x1, y0..y1, ends exclusive: bands of whole rows, or
// spans of one row) whose fragments fit the pool; a pixel's list starts at
//   row_bases[y] + row_offsets[p] - row_offsets[(x0, y)]
// within the pool (row_offsets: exclusive prefix sums of the counts along each row;
// row_bases: where each row of a band starts, 0 for a span).
// A pool entry is uvec4(t* bits, alpha bits, scene index, rank in the front-to-back order).
layout(std430, binding = 9) buffer Counts { uint counts[]; };
layout(std430, binding = 10) buffer RowOffsets { uint row_offsets[]; };
layout(std430, binding = 11) buffer Cursors { uint cursors[]; };
layout(std430, binding = 12) buffer Pool { uvec4 pool[]; };
layout(std430, binding = 13) buffer RowBases { uint row_bases[]; };
// [0]: fragments that found their list full, [1]: lists not filled to their count.
layout(std430, binding = 14) buffer Status { uint status[]; };

uniform int u_width;   // of the image, pixels
uniform ivec4 u_part;  // x0, y0, x1, y1

uint pixel_index(ivec2 p) {
    return uint(p.y) * uint(u_width) + uint(p.x);
}

uint list_start(ivec2 p) {
    return row_bases[p.y] + row_offsets[pixel_index(p)] - row_offsets[pixel_index(ivec2(u_part.x, p.y))];
}

bool in_part(ivec2 p) {
    return all(greaterThanEqual(p, u_part.xy)) && all(lessThan(p, u_part.zw));
}
