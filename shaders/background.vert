#version 450
// G-buffer pass, background: one triangle that covers the viewport (vertices 0, 1, 2 at clip
// (-1, -1), (3, -1), (-1, 3)); the fragment shader computes each pixel's view direction itself.
void main() {
    const vec2 corner = vec2(float((gl_VertexIndex << 1) & 2), float(gl_VertexIndex & 2));
    gl_Position = vec4(2.0 * corner - 1.0, 1.0, 1.0);
}
