// A constant colour, never discarded: every fragment the quads rasterize is blended, so
// a samples-passed query around this pass counts the rasterized fragments.
out vec4 frag_color;

void main() {
    frag_color = vec4(1.0 / 255.0);
}
