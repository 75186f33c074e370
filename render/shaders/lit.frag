#version 330 core
// Vertex colour lit by the scene's light (light.glsl: directional light with
// its shadow-map visibility, headlight, ambient). With PIXEL_RAY the headlight
// direction comes from the pixel's camera ray (render/pixel_ray.py) instead of
// the interpolated camera-relative position v_world, which the draw programs
// then do not output (one vertex output and 3 interpolants fewer).
#ifdef PIXEL_RAY
uniform mat3 u_pixel_ray;  // camera ray through window position (x, y): u_pixel_ray * (x, y, 1)
uniform mat4 u_pixel_inv;  // inverse view-projection: the fragment's camera-relative position from its depth
uniform vec2 u_pixel_size; // viewport, pixels
#else
in vec3 v_world;
#endif
in vec3 v_normal;
in vec4 v_color;

#include "shadow.glsl"
#include "fade.glsl"

out vec4 f_color;

void main() {
    if (fade_discards(ivec2(gl_FragCoord.xy))) discard;
#ifdef PIXEL_RAY
    vec3 world = u_pixel_ray * vec3(gl_FragCoord.xy, 1.0);  // the headlight needs only the direction
    float visibility = 1.0;
    if (u_shadow_on > 0.5) {  // the map needs the position: unprojected from the fragment's window depth
        vec4 p = u_pixel_inv * vec4(gl_FragCoord.xy / u_pixel_size * 2.0 - 1.0, gl_FragCoord.z * 2.0 - 1.0, 1.0);
        visibility = shadow_visibility(p.xyz / p.w, v_normal);
    }
#else
    vec3 world = v_world;
    float visibility = shadow_visibility(v_world, v_normal);
#endif
    f_color = vec4(light_shade(world, v_normal, v_color.rgb, visibility), 1.0);  // v_color: tinted (tint.glsl)
}
