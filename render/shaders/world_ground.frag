#version 330 core
// A subtle metric grid: thin lines every metre, stronger every 10 m, anti-aliased
// with screen-space derivatives (fwidth) and faded with distance and where lines
// would crowd below a few pixels apart (no moire towards the horizon).
in vec3 v_world;
in vec2 v_grid;

uniform vec3 u_ground_color;
#include "world_light.glsl"

out vec4 f_color;

// coverage in [0, 1] of grid lines every `spacing` metres, `width` pixels wide
float grid_lines(vec2 coord, float spacing, float width) {
    vec2 c = coord / spacing;
    vec2 w = max(fwidth(c), vec2(1e-6));
    vec2 d = abs(fract(c - 0.5) - 0.5) / w;  // distance to the nearest line, pixels
    float line = 1.0 - clamp(min(d.x, d.y) - 0.5 * width + 0.5, 0.0, 1.0);
    float crowd = 1.0 - smoothstep(0.08, 0.25, max(w.x, w.y));  // lines closer than ~5 px fade out
    return line * crowd;
}

void main() {
    float dist = length(v_world.xz);
    float minor = grid_lines(v_grid, 1.0, 1.0) * (1.0 - smoothstep(25.0, 60.0, dist));
    float major = grid_lines(v_grid, 10.0, 1.5) * (1.0 - smoothstep(150.0, 400.0, dist));
    vec3 base = u_ground_color * (1.0 - 0.10 * minor) * (1.0 - 0.22 * major);
    f_color = vec4(world_shade(base, vec3(0.0, 1.0, 0.0), v_world), 1.0);
}
