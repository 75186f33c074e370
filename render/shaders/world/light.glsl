// The scene's directional light (render/world/light.py): every character shader and
// the world shaders read these uniforms. u_light_dir: unit direction towards
// the light (world); u_light_color: linear RGB of the direct light;
// u_ambient: ambient factor.
uniform vec3 u_light_dir;
uniform vec3 u_light_color;
uniform float u_ambient;

// Two-sided (back faces are not culled: imported meshes can have inconsistent
// winding) direct light scaled by `visibility` (1 = lit, 0 = in shadow), a
// headlight that keeps silhouettes readable, and the ambient term. With the
// default light (white, ambient 0.3) this is the renderer's original shading.
vec3 light_shade(vec3 world, vec3 normal, vec3 base, float visibility) {
    float ln = dot(normal, normal);
    vec3 n = ln > 1e-20 ? normal * inversesqrt(ln) : vec3(0.0, 1.0, 0.0);
    float lv = dot(world, world);
    vec3 head = lv > 1e-20 ? -world * inversesqrt(lv) : vec3(0.0, 0.0, 1.0);
    vec3 direct = u_light_color * (0.55 * abs(dot(n, u_light_dir)) * visibility);
    return base * (vec3(u_ambient + 0.35 * abs(dot(n, head))) + direct);
}
