#version 330 core
// Vertex colour lit by the scene's light (light.glsl: directional light with
// its shadow-map visibility, headlight, ambient).
in vec3 v_world;
in vec3 v_normal;
in vec4 v_color;

#include "shadow.glsl"
#include "fade.glsl"

out vec4 f_color;

void main() {
    if (fade_discards(ivec2(gl_FragCoord.xy))) discard;
    f_color = vec4(light_shade(v_world, v_normal, v_color.rgb, shadow_visibility(v_world, v_normal)), 1.0);  // v_color: tinted (tint.glsl)
}
