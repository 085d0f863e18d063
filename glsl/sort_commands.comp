// GPU sort, last pass: the indirect draw commands of the order just sorted, from the
// kept count the scan pass wrote on the GPU, so the draw takes its count from there
// (render/gl/renderer.py draws a GPU order through them). One invocation. Five words a
// command, the stride moderngl's render_indirect reads them at (command k at 20 k bytes):
//   0: DrawArraysIndirect, one instance of a 4-vertex strip per splat: (4, n, 0, 0, -)
//   1: DrawArraysIndirect, 6 vertices per splat: (6 n, 1, 0, 0, -)
//   2: DrawElementsIndirect, 6 indices per splat: (6 n, 1, 0, 0, 0)
#include "sort_common.glsl"

layout(local_size_x = 1) in;
layout(std430, binding = 7) writeonly buffer Commands { uint commands[]; };

void main() {
    uint n = summary.visible;
    commands[0] = 4u;      commands[1] = n;   commands[2] = 0u;   commands[3] = 0u;   commands[4] = 0u;
    commands[5] = 6u * n;  commands[6] = 1u;  commands[7] = 0u;   commands[8] = 0u;   commands[9] = 0u;
    commands[10] = 6u * n; commands[11] = 1u; commands[12] = 0u;  commands[13] = 0u;  commands[14] = 0u;
}
