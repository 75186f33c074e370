// Shadow-map lookup (render/world/shadows.py, [render] shadows = "map"): an
// orthographic depth map rendered from the light, fitted to the visible
// casters, sampled with 3x3 percentage-closer filtering (Reeves, Salesin &
// Cook 1987) on a depth-comparing sampler (each tap is itself a bilinear 2x2
// comparison). Positions are camera-relative world positions, as the
// vertex shaders output them; u_light_vp maps them to the light's clip space.
#include "light.glsl"

uniform sampler2DShadow u_shadow_map;
uniform mat4 u_light_vp;
uniform float u_shadow_on;      // 1: sample the map; 0: everything lit (no map, or the map's own pass)
uniform vec3 u_shadow_params;   // (texel size in uv, depth bias, normal offset in metres)

float shadow_visibility(vec3 world, vec3 normal) {
#ifndef SHADOW_MAP
    // a renderer without shadow maps ([render] shadows other than "map") compiles no lookup: llvmpipe runs a
    // branch on a uniform under a lane mask, both ways, so the nine lookups below cost every lit pixel ~1 ms
    // each a 1280x720 frame even with u_shadow_on = 0 (render.renderer.Renderer.program)
    return 1.0;
#else
    if (u_shadow_on < 0.5) return 1.0;
    float ln = dot(normal, normal);
    vec3 n = ln > 1e-20 ? normal * inversesqrt(ln) : u_light_dir;
    if (dot(n, u_light_dir) < 0.0) n = -n;  // two-sided: offset towards the light
    vec4 c = u_light_vp * vec4(world + n * u_shadow_params.z, 1.0);
    vec3 p = c.xyz / c.w * 0.5 + 0.5;
    if (p.x < 0.0 || p.x > 1.0 || p.y < 0.0 || p.y > 1.0 || p.z < 0.0) return 1.0;
    // beyond the far plane: compare against the far plane (a cleared texel stays lit)
    float ref = min(p.z, 1.0) - u_shadow_params.y;
    float s = 0.0;
    for (int y = -1; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x)
            s += texture(u_shadow_map, vec3(p.xy + vec2(x, y) * u_shadow_params.x, ref));
    return s / 9.0;
#endif
}
