#version 460
// hybrid_mesh_id.frag — the visibility pass: the nearest triangle's number + 1 per pixel
// (0 where no triangle is: the background). See hybrid_mesh_id.vert.

layout(location = 0) flat in uint in_triangle;
layout(location = 0) out uint out_id;

void main() {
    out_id = in_triangle;
}
