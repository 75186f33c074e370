#version 430
// Shading pass of the compute rasteriser (render/raster/frame.py): one fragment per pixel of the screen
// rectangle the frame's compute-rasterised instances cover (points_resolve.vert). A pixel some triangle won
// (Depth, Ids: raster_tri.glsl) reads that triangle back (job, instance, its three vertices: raster_common.glsl),
// finds the point its pixel-centre ray meets (perspective-correct barycentrics of the camera-relative
// triangle: Moeller & Trumbore's ray-triangle solution, the camera at the origin), interpolates the
// instance-transformed normal and the tinted colour of its vertices as the hardware path's vertex stage
// feeds its fragment stage, and shades them with the very functions of that stage (lit_shade.glsl for
// characters, world_light.glsl for props and obstacle solids). It writes the triangle's depth to
// gl_FragDepth, so the depth test composes it with what the hardware path drew.
#include "raster_common.glsl"
#include "tint.glsl"
#include "lit_shade.glsl"
#include "world_light.glsl"

layout(std430, binding = 0) readonly buffer Depth { uint depth[]; };
layout(std430, binding = 1) readonly buffer Ids { uint ids[]; };
uniform ivec2 u_size;
#ifndef PIXEL_RAY
uniform mat3 u_pixel_ray;
#endif
out vec4 f_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    uint at = uint(px.y * u_size.x + px.x);
    uint key = depth[at];
    if (key == 0xFFFFFFFFu) discard;
    uint id = ids[at];
    uvec4 job = rs_job(id >> RS_LOG_CHUNK);
    RsInstance r = rs_instance(job.z);
    uvec3 t = rs_triangle(job.x + (id & (RS_CHUNK - 1u)));
    vec3 p0, p1, p2, n0, n1, n2;
    vec4 c0, c1, c2;
    rs_vertex(r, t.x, p0, n0, c0);
    rs_vertex(r, t.y, p1, n1, c1);
    rs_vertex(r, t.z, p2, n2, c2);
    vec3 a = rs_point(r, p0);
    vec3 e1 = rs_point(r, p1) - a;
    vec3 e2 = rs_point(r, p2) - a;
    // the pixel centre's ray from the camera (the origin of the camera-relative frame)
    vec3 d = u_pixel_ray * vec3(gl_FragCoord.xy, 1.0);
    vec3 pv = cross(d, e2);
    float det = dot(e1, pv);
    float inv = abs(det) > 0.0 ? 1.0 / det : 0.0;
    vec3 s = -a;
    float b1 = dot(s, pv) * inv;
    vec3 qv = cross(s, e1);
    float b2 = dot(d, qv) * inv;
    // the ray of a covered pixel centre meets the triangle; rounding may put it a hair outside
    b1 = clamp(b1, 0.0, 1.0);
    b2 = clamp(b2, 0.0, 1.0 - b1);
    float b0 = 1.0 - b1 - b2;
    vec3 normal = rs_dir(r, b0 * n0 + b1 * n1 + b2 * n2);
    vec3 world = a + b1 * e1 + b2 * e2;
    float z = uintBitsToFloat(key);
    gl_FragDepth = z;
    if ((r.flags & RS_WORLD) != 0u) {
        // props and obstacle solids: world_mesh.frag (their debug tint rides in the instance's debug word)
        vec4 c = b0 * c0 + b1 * c1 + b2 * c2;
        vec4 dbg = tint_bytes(r.tint.y) / 255.0;
        f_color = vec4(world_shade(mix(c.rgb, dbg.rgb, dbg.a), normal, world), 1.0);
        return;
    }
    vec4 c = b0 * tint_color(c0, r.tint) + b1 * tint_color(c1, r.tint) + b2 * tint_color(c2, r.tint);
    f_color = vec4(lit_shade(vec3(gl_FragCoord.xy, z), world, normal, c.rgb), 1.0);
}
