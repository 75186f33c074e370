#version 330 core
// A subtle metric grid: thin lines every metre, stronger every 10 m, anti-aliased
// with screen-space derivatives (fwidth, taken once: the 10 m grid's is a tenth)
// and faded with distance and where lines would crowd closer than a few pixels
// (no moire towards the horizon). Kept cheap: on llvmpipe the ground covers most
// pixels, so the line terms are skipped where they have faded out.
in vec3 v_world;
in vec2 v_grid;

uniform vec3 u_ground_color;
#include "world_light.glsl"

out vec4 f_color;

// coverage in [0, 1] of lines every `spacing` metres, `width` pixels wide; w = metres per pixel along x, z
float grid_lines(vec2 coord, float spacing, vec2 w, float width) {
    vec2 d = abs(fract(coord / spacing - 0.5) - 0.5) * spacing / w;  // distance to the nearest line, pixels
    return 1.0 - clamp(min(d.x, d.y) - 0.5 * width + 0.5, 0.0, 1.0);
}

void main() {
    vec2 w = max(fwidth(v_grid), vec2(1e-6));
    float crowd = max(w.x, w.y);
    float dist = length(v_world.xz);
    float dark = 0.0;
    float minor = (1.0 - smoothstep(25.0, 60.0, dist)) * (1.0 - smoothstep(0.08, 0.25, crowd));
    if (minor > 0.0) dark += 0.10 * minor * grid_lines(v_grid, 1.0, w, 1.0);
    float major = (1.0 - smoothstep(150.0, 400.0, dist)) * (1.0 - smoothstep(0.8, 2.5, crowd));
    if (major > 0.0) dark += 0.22 * major * grid_lines(v_grid, 10.0, w, 1.5);
    f_color = vec4(world_shade(u_ground_color * (1.0 - dark), vec3(0.0, 1.0, 0.0), v_world), 1.0);
}
