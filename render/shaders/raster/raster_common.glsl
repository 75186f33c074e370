// Shared declarations of the compute rasteriser (render/raster/): the frame's tables as textures
// (on llvmpipe a texelFetch costs a fraction of a per-lane storage-buffer load: render/raster/__init__.py),
// every one 4096 texels wide, texel t at (t & 4095, t >> 12).
//
//   u_rs_tris  (RGBA32UI) one texel per triangle of every uploaded mesh: its corner vertices (a, b, c, 0),
//                         relative to the mesh's first vertex record;
//   u_rs_mesh  (RGBA32UI) RS_RECORD texels per vertex record, floats as bits: (p.xyz, n.x), (n.y, n.z, c.r,
//                         c.g), (c.b, c.a, 0, 0); a keyframed mesh has a record per vertex at u = 0, then one
//                         per vertex at u = 1 (Wand & Strasser 2002, section 3);
//   u_rs_posed (RGBA32F)  RS_POSED texels per posed vertex (p.xyz, n.x), (n.y, n.z, 0, 0): skinned instances'
//                         vertices in the model frame (the pose cache's [slot][vertex] layout);
//   u_rs_inst  (RGBA32UI) RS_INST texels per instance of the frame: model rows 0..2 (camera-relative, as
//                         lod/drawlist.py), (u, kind | flags << 8, first mesh record, first posed vertex),
//                         (first screen vertex, variation word, debug word, vertices);
//   u_rs_jobs  (RGBA32UI) one texel per job: (first triangle, triangles <= RS_CHUNK, instance, 0).
// A triangle's id is job * RS_CHUNK + its index in the job (render/raster/frame.py).
#define RS_RECORD 3u
#define RS_POSED 2u
#define RS_INST 5u
#ifndef RS_LOG_CHUNK
#define RS_LOG_CHUNK 10
#endif
#define RS_CHUNK (1u << RS_LOG_CHUNK)
// instance kinds and flags
#define RS_STATIC 0u
#define RS_KEYFRAMED 1u
#define RS_POSED_KIND 2u
#define RS_CULL 1u    // single-sided: back faces culled
#define RS_WORLD 2u   // shaded as the world (world_light.glsl), not as a character

uniform usampler2D u_rs_tris;
uniform usampler2D u_rs_mesh;
uniform sampler2D u_rs_posed;
uniform usampler2D u_rs_inst;
uniform usampler2D u_rs_jobs;

ivec2 rs_texel(uint t) { return ivec2(int(t & 4095u), int(t >> 12)); }

struct RsInstance {
    vec4 m0;
    vec4 m1;
    vec4 m2;
    float u;
    uint kind;
    uint flags;
    uint mesh;
    uint posed;
    uint screen;
    uvec2 tint;
    uint verts;
};

RsInstance rs_instance(uint i) {
    uint t = i * RS_INST;
    RsInstance r;
    r.m0 = uintBitsToFloat(texelFetch(u_rs_inst, rs_texel(t), 0));
    r.m1 = uintBitsToFloat(texelFetch(u_rs_inst, rs_texel(t + 1u), 0));
    r.m2 = uintBitsToFloat(texelFetch(u_rs_inst, rs_texel(t + 2u), 0));
    uvec4 a = texelFetch(u_rs_inst, rs_texel(t + 3u), 0);
    uvec4 b = texelFetch(u_rs_inst, rs_texel(t + 4u), 0);
    r.u = clamp(uintBitsToFloat(a.x), 0.0, 1.0);
    r.kind = a.y & 255u;
    r.flags = a.y >> 8;
    r.mesh = a.z;
    r.posed = a.w;
    r.screen = b.x;
    r.tint = b.yz;
    r.verts = b.w;
    return r;
}

// the camera-relative world position of model point p (instance.glsl instance_point, from the rows)
vec3 rs_point(RsInstance r, vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(r.m0, h), dot(r.m1, h), dot(r.m2, h));
}

vec3 rs_dir(RsInstance r, vec3 d) {
    return vec3(dot(r.m0.xyz, d), dot(r.m1.xyz, d), dot(r.m2.xyz, d));
}

void rs_record(uint rec, out vec3 p, out vec3 n, out vec4 c) {
    uint t = rec * RS_RECORD;
    uvec4 a = texelFetch(u_rs_mesh, rs_texel(t), 0);
    uvec4 b = texelFetch(u_rs_mesh, rs_texel(t + 1u), 0);
    uvec4 d = texelFetch(u_rs_mesh, rs_texel(t + 2u), 0);
    p = uintBitsToFloat(a.xyz);
    n = uintBitsToFloat(uvec3(a.w, b.xy));
    c = uintBitsToFloat(uvec4(b.zw, d.xy));
}

vec3 rs_record_position(uint rec) {
    return uintBitsToFloat(texelFetch(u_rs_mesh, rs_texel(rec * RS_RECORD), 0).xyz);
}

// model-frame position of vertex v of instance r (what the vertex stage of the hardware path computes before
// the instance transform: static.vert, keyframed.vert, the pose cache's posed vertex)
vec3 rs_position(RsInstance r, uint v) {
    if (r.kind == RS_POSED_KIND) return texelFetch(u_rs_posed, rs_texel((r.posed + v) * RS_POSED), 0).xyz;
    vec3 p = rs_record_position(r.mesh + v);
    if (r.kind == RS_KEYFRAMED) p = mix(p, rs_record_position(r.mesh + r.verts + v), r.u);
    return p;
}

// position, normal and colour of vertex v of instance r in the model frame
void rs_vertex(RsInstance r, uint v, out vec3 p, out vec3 n, out vec4 c) {
    rs_record(r.mesh + v, p, n, c);
    if (r.kind == RS_KEYFRAMED) {
        vec3 p1;
        vec3 n1;
        vec4 c1;
        rs_record(r.mesh + r.verts + v, p1, n1, c1);
        p = mix(p, p1, r.u);
        n = mix(n, n1, r.u);
        c = mix(c, c1, r.u);
    } else if (r.kind == RS_POSED_KIND) {
        uint t = (r.posed + v) * RS_POSED;
        vec4 a = texelFetch(u_rs_posed, rs_texel(t), 0);
        vec4 b = texelFetch(u_rs_posed, rs_texel(t + 1u), 0);
        p = a.xyz;
        n = vec3(a.w, b.xy);
    }
}

// job j: (first triangle, count, instance)
uvec4 rs_job(uint j) { return texelFetch(u_rs_jobs, rs_texel(j), 0); }

uvec3 rs_triangle(uint t) { return texelFetch(u_rs_tris, rs_texel(t), 0).xyz; }
