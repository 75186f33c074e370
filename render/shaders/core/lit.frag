#version 330 core
// Vertex colour lit by the scene's light (lit_shade.glsl: directional light with its shadow-map
// visibility, headlight, ambient). With PIXEL_RAY the headlight direction comes from the pixel's camera ray
// (render/screen.py) instead of the interpolated camera-relative position v_world, which the draw
// programs then do not output (one vertex output and 3 interpolants fewer).
#ifndef PIXEL_RAY
in vec3 v_world;
#endif
in vec3 v_normal;
in vec4 v_color;

#include "lit_shade.glsl"
#include "fade.glsl"

out vec4 f_color;

void main() {
    if (fade_discards(ivec2(gl_FragCoord.xy))) discard;
#ifdef PIXEL_RAY
    vec3 world = vec3(0.0);
#else
    vec3 world = v_world;
#endif
    f_color = vec4(lit_shade(gl_FragCoord.xyz, world, v_normal, v_color.rgb), 1.0);  // v_color: tinted (tint.glsl)
}
