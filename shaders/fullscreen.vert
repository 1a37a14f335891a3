#version 460
// fullscreen.vert — one triangle covering the viewport (no vertex buffer). uv is 0..1
// across the image with v = 0 at the top row, matching our image convention.
layout(location = 0) out vec2 out_uv;

void main() {
    vec2 p = vec2((gl_VertexIndex << 1) & 2, gl_VertexIndex & 2);
    out_uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
