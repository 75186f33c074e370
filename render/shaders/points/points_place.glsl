#version 430
// Samples placed with the animation (render/points/follow.py, lod/points/follow.py): one work item per
// sample of a pose's sample prefix. A job (points_jobs.glsl) is one distinct pose: (first output slot,
// sample count, first posed vertex of the pose, exclusive prefix). A sample (triangle, barycentric) is the
// barycentric blend of its triangle's posed corners (points_pose.glsl wrote them), so it lies on the
// triangle full detail draws; its filtered normal (Wand & Strasser section 3.5) is kept in the frame of the
// interpolated vertex normal N and the triangle's first edge (T made orthogonal to N, B = N x T) and turned
// with it. Colour: the filtered colour, which the animation does not change.
#ifndef LOCAL_SIZE
#define LOCAL_SIZE 64
#endif
layout(local_size_x = LOCAL_SIZE) in;
#include "points_jobs.glsl"
#include "points_placed.glsl"
// (triangle, barycentric b1 | b2 as unorm16x2, colour RGBA8, normal in the shading frame, octahedral)
layout(std430, binding = 6) readonly buffer Samples { uvec4 samples[]; };
layout(std430, binding = 5) readonly buffer Corners { uint corners[]; };
layout(std430, binding = 9) buffer Placed { uvec4 placed[]; };
uniform uint u_items;

void main() {
    uint g = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * uint(LOCAL_SIZE);
    if (g >= u_items) return;
    uint j = find_job(g);
    uvec4 job = jobs[j];
    uint k = g - job.w;
    uvec4 s = samples[k];
    vec2 b = unpackUnorm2x16(s.y);
    float b0 = 1.0 - b.x - b.y;
    uint t = 3u * s.x;
    uvec4 w0 = placed[job.z + corners[t]];
    uvec4 w1 = placed[job.z + corners[t + 1u]];
    uvec4 w2 = placed[job.z + corners[t + 2u]];
    vec3 p0 = placed_pos(w0);
    vec3 p1 = placed_pos(w1);
    vec3 p = b0 * p0 + b.x * p1 + b.y * placed_pos(w2);
    vec3 nv = b0 * oct_decode(w0.z) + b.x * oct_decode(w1.z) + b.y * oct_decode(w2.z);
    float ln = dot(nv, nv);
    vec3 N = ln > 1e-20 ? nv * inversesqrt(ln) : vec3(0.0, 1.0, 0.0);
    vec3 e = p1 - p0;
    vec3 T = e - dot(e, N) * N;
    float lt = dot(T, T);
    vec3 n = N;
    if (lt > 1e-20) {
        T *= inversesqrt(lt);
        vec3 l = oct_decode(s.w);
        n = l.x * T + l.y * cross(N, T) + l.z * N;
    }
    placed[job.x + k] = uvec4(packUnorm2x16(p.xy), packUnorm2x16(vec2(p.z, 0.0)), oct_encode(n), s.z);
}
