#version 330 core
#include "instance.glsl"

in vec3 in_position;
in vec3 in_normal;
in vec4 in_color;

uniform mat4 u_view_proj;

out vec3 v_world;
out vec3 v_normal;
out vec4 v_color;

void main() {
    v_world = instance_point(in_position);
    v_normal = instance_dir(in_normal);
    v_color = tint_color(in_color, i_tint);
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
