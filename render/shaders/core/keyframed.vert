#version 330 core
#include "instance.glsl"

// Keyframe segment vertex (Wand & Strasser 2002, section 3): start and end
// attributes, mixed by the instance's u = i_anim.x in [0, 1].
in vec3 in_position0;
in vec3 in_position1;
in vec3 in_normal0;
in vec3 in_normal1;
in vec4 in_color0;
in vec4 in_color1;

uniform mat4 u_view_proj;

out vec3 v_world;
out vec3 v_normal;
out vec4 v_color;

void main() {
    float u = clamp(i_anim.x, 0.0, 1.0);
    v_world = instance_point(mix(in_position0, in_position1, u));
    v_normal = instance_dir(mix(in_normal0, in_normal1, u));
    v_color = tint_color(mix(in_color0, in_color1, u), i_tint);
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
