#version 460
// hybrid_sky.vert — one triangle over the whole target, just in front of the far plane,
// so that the mesh pass's sky (hybrid_sky.frag) is drawn first and every mesh fragment
// covers it (depth test LESS against the cleared 1.0).

void main() {
    vec2 p = vec2(float((gl_VertexIndex << 1) & 2), float(gl_VertexIndex & 2));
    // 1 - 2^-24: the largest depth below the clear value.
    gl_Position = vec4(2.0 * p - 1.0, 0.99999994, 1.0);
}
