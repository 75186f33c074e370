#version 430
// Triangles selected by the octree traversal (section 3.2), pulled per vertex:
// work item = triangle * 3 + corner; Items holds one (triangle of the
// segments' tri_order list, instance) per triangle (render/points.py
// expand_jobs), so no vertex searches for its job.
#include "points_common.glsl"
layout(std430, binding = 5) readonly buffer Verts { Sample verts[]; };
layout(std430, binding = 6) readonly buffer Corners { uint corners[]; };
layout(std430, binding = 7) readonly buffer Items { uvec2 items[]; };
uniform mat4 u_view_proj;
out vec3 v_world;
out vec3 v_normal;
out vec4 v_color;

void main() {
    uint g = uint(gl_VertexID) / 3u;
    uint corner = uint(gl_VertexID) - 3u * g;
    uvec2 it = items[g];
    uint i = it.y;
    uint v = corners[3u * it.x + corner];
    vec3 p;
    vec3 n;
    vec4 c;
    sample_at(verts[v], inst_u(i), p, n, c);
    v_world = inst_point(i, p);
    v_normal = inst_dir(i, n);
    v_color = c;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
