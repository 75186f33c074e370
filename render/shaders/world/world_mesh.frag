#version 330 core
in vec3 v_world;
in vec3 v_normal;
in vec4 v_color;

uniform vec4 u_tint;  // debug colouring: rgb mixed in with weight a
#include "world_light.glsl"

out vec4 f_color;

void main() {
    vec3 base = mix(v_color.rgb, u_tint.rgb, u_tint.a);
    f_color = vec4(world_shade(base, v_normal, v_world), 1.0);
}
