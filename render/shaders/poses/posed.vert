#version 330 core
// A copy drawn from the pose cache (render/poses/cache.py, posed.glsl): its
// vertices were skinned once for its pose slot (i_anim.y) by pose_skin.comp,
// so the vertex stage reads them and applies only the instance transform.
#include "instance.glsl"
#include "posed.glsl"

in vec4 in_color;

uniform mat4 u_view_proj;

out vec3 v_world;   // camera-relative world position
out vec3 v_normal;
out vec4 v_color;

void main() {
    int slot = int(i_anim.y + 0.5);
    vec3 p;
    vec3 n;
    posed_vertex(slot, gl_VertexID, p, n);
    v_world = instance_point(p);
    v_normal = instance_dir(n);
    v_color = tint_color(in_color, i_tint);
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
