#version 330 core
// Vertex colour lit by a fixed sun and a headlight, two-sided (back faces are
// not culled: imported meshes can have inconsistent winding), plus ambient.
in vec3 v_world;
in vec3 v_normal;
in vec4 v_color;

uniform vec3 u_sun;       // unit direction towards the sun, world
uniform float u_ambient;
#include "fade.glsl"

out vec4 f_color;

void main() {
    if (fade_discards(ivec2(gl_FragCoord.xy))) discard;
    float ln = dot(v_normal, v_normal);
    vec3 n = ln > 1e-20 ? v_normal * inversesqrt(ln) : vec3(0.0, 1.0, 0.0);
    float lv = dot(v_world, v_world);
    vec3 head = lv > 1e-20 ? -v_world * inversesqrt(lv) : vec3(0.0, 0.0, 1.0);
    float diffuse = 0.55 * abs(dot(n, u_sun)) + 0.35 * abs(dot(n, head));
    f_color = vec4(v_color.rgb * (u_ambient + diffuse), 1.0);  // v_color: tinted (tint.glsl)
}
