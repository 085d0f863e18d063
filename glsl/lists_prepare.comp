// Fragment lists, before a part's fill pass: every pixel's cursor at its list's start.
#include "fragment_lists.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    ivec2 p = u_part.xy + ivec2(gl_GlobalInvocationID.xy);
    if (!in_part(p)) return;
    cursors[pixel_index(p)] = list_start(p);
}
