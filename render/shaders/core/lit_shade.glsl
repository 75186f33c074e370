// The lit colour of a character's surface point (light.glsl: directional light with its shadow-map
// visibility, headlight, ambient), shared by lit.frag (the hardware path's fragment stage) and the compute
// rasteriser's shading pass (raster_shade.frag), so both shade a pixel alike. frag: the window position
// (gl_FragCoord.xy) and depth of the point; world: its camera-relative position (used without PIXEL_RAY);
// normal and color: as the vertex stage interpolates them (color tinted, tint.glsl). With PIXEL_RAY the
// headlight direction comes from the pixel's camera ray (render/screen.py) and the shadow map's lookup
// position is unprojected from the window depth, so no position needs interpolating.
#ifdef PIXEL_RAY
uniform mat3 u_pixel_ray;  // camera ray through window position (x, y): u_pixel_ray * (x, y, 1)
uniform mat4 u_pixel_inv;  // inverse view-projection: the fragment's camera-relative position from its depth
uniform vec2 u_pixel_size; // viewport, pixels
#endif

#include "shadow.glsl"

vec3 lit_shade(vec3 frag, vec3 world, vec3 normal, vec3 color) {
#ifdef PIXEL_RAY
    vec3 ray = u_pixel_ray * vec3(frag.xy, 1.0);  // the headlight needs only the direction
    float visibility = 1.0;
    if (u_shadow_on > 0.5) {  // the map needs the position: unprojected from the fragment's window depth
        vec4 p = u_pixel_inv * vec4(frag.xy / u_pixel_size * 2.0 - 1.0, frag.z * 2.0 - 1.0, 1.0);
        visibility = shadow_visibility(p.xyz / p.w, normal);
    }
    return light_shade(ray, normal, color, visibility);
#else
    return light_shade(world, normal, color, shadow_visibility(world, normal));
#endif
}
