#version 330 core
// A subtle metric grid: thin lines every metre, stronger every 10 m, anti-aliased
// with screen-space derivatives (one fwidth: metres per pixel) and fading with
// distance as the lines crowd together on screen (the 1 m lines are gone where
// they would be closer than ~8 pixels, the 10 m ones where closer than ~8 pixels
// too), so the horizon shows no moire. Kept to a few arithmetic operations per
// pixel: on llvmpipe the ground covers most of the frame.
in vec3 v_world;
in vec2 v_grid;

uniform vec3 u_ground_color;
#include "world_light.glsl"

out vec4 f_color;

void main() {
    vec2 w = max(fwidth(v_grid), vec2(1e-6));                   // metres per pixel along x, z
    float m = max(w.x, w.y);
    vec2 a = abs(fract(v_grid - 0.5) - 0.5) / w;                // pixels to the nearest 1 m line
    vec2 b = abs(fract(v_grid * 0.1 - 0.5) - 0.5) * 10.0 / w;   // pixels to the nearest 10 m line
    float minor = clamp(1.0 - min(a.x, a.y), 0.0, 1.0) * clamp(1.5 - 12.0 * m, 0.0, 1.0);
    float major = clamp(1.25 - min(b.x, b.y), 0.0, 1.0) * clamp(1.5 - 1.2 * m, 0.0, 1.0);
    vec3 base = u_ground_color * (1.0 - 0.10 * minor - 0.22 * major);
    f_color = vec4(world_shade_ground(base, v_world), 1.0);
}
