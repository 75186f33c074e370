#version 330 core
// Vertex colour lit by the scene's light (light.glsl: directional light with
// its shadow-map visibility, headlight, ambient).
in vec3 v_world;
in vec3 v_normal;
in vec4 v_color;

#include "shadow.glsl"
uniform vec4 u_tint;     // debug colouring: rgb mixed in with weight a (0 = true colours)
#include "fade.glsl"

out vec4 f_color;

void main() {
    if (fade_discards(ivec2(gl_FragCoord.xy))) discard;
    vec3 base = mix(v_color.rgb, u_tint.rgb, u_tint.a);
    f_color = vec4(light_shade(v_world, v_normal, base, shadow_visibility(v_world, v_normal)), 1.0);
}
