#version 430
// The hardware path for the triangles the compute rasteriser's depth pass set aside (raster_tri.glsl: too
// large on screen, or crossing the near plane): one vertex per corner of a listed triangle, pulled from the
// same tables (raster_common.glsl) and fed to the fragment stage as the instanced draws feed it (lit.frag;
// RS_WORLD_SPILL: props and obstacle solids, world_mesh.frag, their debug colour mixed in here, u_tint 0).
#include "raster_common.glsl"
#include "tint.glsl"

layout(std430, binding = 4) readonly buffer Spill { uint spill[]; };
uniform mat4 u_view_proj;
uniform uint u_first;  // first entry of this draw's list in Spill

#if !defined(PIXEL_RAY) || defined(RS_WORLD_SPILL)
out vec3 v_world;
#endif
out vec3 v_normal;
out vec4 v_color;

void main() {
    uint id = spill[u_first + uint(gl_VertexID) / 3u];
    uvec4 job = rs_job(id >> RS_LOG_CHUNK);
    RsInstance r = rs_instance(job.z);
    uvec3 t = rs_triangle(job.x + (id & (RS_CHUNK - 1u)));
    uint corner = uint(gl_VertexID) % 3u;
    uint v = corner == 0u ? t.x : (corner == 1u ? t.y : t.z);
    vec3 p, n;
    vec4 c;
    rs_vertex(r, v, p, n, c);
    vec3 world = rs_point(r, p);
#if !defined(PIXEL_RAY) || defined(RS_WORLD_SPILL)
    v_world = world;
#endif
    v_normal = rs_dir(r, n);
#ifdef RS_WORLD_SPILL
    vec4 dbg = tint_bytes(r.tint.y) / 255.0;
    v_color = vec4(mix(c.rgb, dbg.rgb, dbg.a), c.a);
#else
    v_color = tint_color(c, r.tint);
#endif
    gl_Position = u_view_proj * vec4(world, 1.0);
}
