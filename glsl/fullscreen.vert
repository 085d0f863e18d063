// The vertex stage of every full-screen pass (resolve, present, lens, stereo compose):
// a full-viewport triangle; the viewport itself places the image (letterboxing).
out vec2 v_uv;  // 0..1 across the viewport, origin at its lower-left corner

void main() {
    vec2 corner = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    v_uv = corner;
    gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
