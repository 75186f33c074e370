#version 430
// Reference path: the selected points as GL_POINTS of size u_splat, pulled
// from the same point buffer; one work item (sample, instance) per vertex.
#include "points_common.glsl"
#ifdef PLACED
// posed vertices / placed samples of this frame (render/points/follow.py, points_placed.glsl)
layout(std430, binding = 0) readonly buffer Placed { uvec4 placed[]; };
#else
layout(std430, binding = 0) readonly buffer Points { Sample pts[]; };
#endif
layout(std430, binding = 7) readonly buffer Items { uvec2 items[]; };
uniform mat4 u_view_proj;
uniform float u_splat;
out vec3 v_world;
out vec3 v_normal;
out vec4 v_color;

void main() {
    uvec2 it = items[gl_VertexID];
    uint i = it.y;
    vec3 p;
    vec3 n;
    vec4 c;
#ifdef PLACED
    placed_at(placed[it.x], p, n, c);
#else
    sample_at(pts[it.x], inst_u(i), p, n, c);
#endif
    v_world = inst_point(i, p);
    v_normal = inst_dir(i, n);
    v_color = tint_color(c, tints[i]);
    gl_PointSize = u_splat;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
