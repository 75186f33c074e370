// Shading of the world (ground, obstacle solids, props): the scene's directional
// light (light.glsl, render/world/light.py: u_light_dir, u_light_color, u_ambient, set
// with the characters' by render.shadows.Lighting.apply), Lambert, two-sided (a
// face seen from behind is lit as its front), its direct term multiplied by the
// shadow map's visibility (shadow.glsl; 1 without a map). Positions are
// camera-relative (the eye at the origin), as shadow.glsl expects.
// The one place the world's lighting lives: extend world_shade (more lights).
#include "shadow.glsl"

// direct share facing the light: with the default ambient 0.3 a white-lit face
// facing the light shows its base colour (ambient + WORLD_DIRECT = 1)
const float WORLD_DIRECT = 0.7;

vec3 world_shade(vec3 base, vec3 normal, vec3 rel_pos) {
    float ln = dot(normal, normal);
    vec3 n = ln > 1e-20 ? normal * inversesqrt(ln) : vec3(0.0, 1.0, 0.0);
    if (dot(n, -rel_pos) < 0.0) n = -n;  // camera-relative position: the eye is at the origin
    float lambert = max(dot(n, u_light_dir), 0.0);
    float vis = lambert > 0.0 ? shadow_visibility(rel_pos, n) : 1.0;  // no lookup where no direct light falls
    return base * (vec3(u_ambient) + u_light_color * (WORLD_DIRECT * lambert * vis));
}

// world_shade for the ground plane (normal +Y, or -Y seen from below): the same terms without the
// per-pixel normal work (the ground covers most pixels). Extend it together with world_shade.
vec3 world_shade_ground(vec3 base, vec3 rel_pos) {
    float up = rel_pos.y <= 0.0 ? 1.0 : -1.0;
    float lambert = max(up * u_light_dir.y, 0.0);
    float vis = lambert > 0.0 ? shadow_visibility(rel_pos, vec3(0.0, up, 0.0)) : 1.0;
    return base * (vec3(u_ambient) + u_light_color * (WORLD_DIRECT * lambert * vis));
}
