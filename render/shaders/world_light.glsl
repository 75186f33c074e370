// Shading of the world (ground, obstacle solids, props): one directional light
// (Lambert) plus ambient, two-sided (a face seen from behind is lit as its front).
// The one place the world's lighting lives: extend world_shade (shadows, more lights).
uniform vec3 u_light_dir;   // unit direction towards the light, world
uniform float u_ambient;    // ambient share in [0, 1]

vec3 world_shade(vec3 base, vec3 normal, vec3 rel_pos) {
    float ln = dot(normal, normal);
    vec3 n = ln > 1e-20 ? normal * inversesqrt(ln) : vec3(0.0, 1.0, 0.0);
    if (dot(n, -rel_pos) < 0.0) n = -n;  // camera-relative position: the eye is at the origin
    float lambert = max(dot(n, u_light_dir), 0.0);
    return base * (u_ambient + (1.0 - u_ambient) * lambert);
}

// world_shade for the ground plane (normal +Y, or -Y seen from below): the same Lambert term without the
// per-pixel normal work (the ground covers most pixels). Extend it together with world_shade.
vec3 world_shade_ground(vec3 base, vec3 rel_pos) {
    float lambert = max(rel_pos.y <= 0.0 ? u_light_dir.y : -u_light_dir.y, 0.0);
    return base * (u_ambient + (1.0 - u_ambient) * lambert);
}
