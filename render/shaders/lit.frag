#version 330 core
// Vertex colour lit by a fixed sun and a headlight, two-sided (the back faces
// of double-sided meshes are drawn), plus ambient. With PIXEL_RAY the headlight
// direction comes from the pixel's camera ray (render/pixel_ray.py) instead of
// the interpolated camera-relative position v_world, which the draw programs
// then do not output (one vertex output and 3 interpolants fewer).
#ifdef PIXEL_RAY
uniform mat3 u_pixel_ray;  // camera ray through window position (x, y): u_pixel_ray * (x, y, 1)
#else
in vec3 v_world;
#endif
in vec3 v_normal;
in vec4 v_color;

uniform vec3 u_sun;       // unit direction towards the sun, world
uniform float u_ambient;
uniform vec4 u_tint;     // debug colouring: rgb mixed in with weight a (0 = true colours)
#include "fade.glsl"

out vec4 f_color;

void main() {
    if (fade_discards(ivec2(gl_FragCoord.xy))) discard;
    float ln = dot(v_normal, v_normal);
    vec3 n = ln > 1e-20 ? v_normal * inversesqrt(ln) : vec3(0.0, 1.0, 0.0);
#ifdef PIXEL_RAY
    vec3 ray = u_pixel_ray * vec3(gl_FragCoord.xy, 1.0);
#else
    vec3 ray = v_world;
#endif
    float lv = dot(ray, ray);
    vec3 head = lv > 1e-20 ? -ray * inversesqrt(lv) : vec3(0.0, 0.0, 1.0);
    float diffuse = 0.55 * abs(dot(n, u_sun)) + 0.35 * abs(dot(n, head));
    vec3 base = mix(v_color.rgb, u_tint.rgb, u_tint.a);
    f_color = vec4(base * (u_ambient + diffuse), 1.0);
}
