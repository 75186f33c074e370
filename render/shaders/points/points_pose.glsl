#version 430
// Posed vertices of the representations whose samples follow the animation (render/points/follow.py,
// lod/points/follow.py): one work item per vertex of a pose's vertex prefix. A job (points_jobs.glsl) is
// one distinct pose of the frame: (first output slot, vertex count, pose word, exclusive prefix).
// Skinned, POSE_SLOT (the default path): the pose word is the pose's slot in the pose cache's palettes
// (render/poses/cache.py: the frame's one evaluation of each pose) and pose_u[job] its frame (for the morph
// targets' weights); the vertex is morphed, then linear blend skinned with the slot's matrices (skin ∘ morph:
// the arithmetic of the skinned draw, skinning.glsl palette_rows and targets.glsl targets_apply).
// Skinned without POSE_SLOT (no pose palette this frame): the pose word is the float bits of the fractional
// baked row, the matrices blended from the joint table (skin_rows).
// KEYFRAMED: the pose word is the first vertex of the segment in u_kverts (whose vertices are the
// segment's start and end, render/points/samples.py pack_samples) and u comes from pose_u[job]; the vertex
// is their interpolation (Wand & Strasser section 3).
// Output: placed[] (points_placed.glsl), positions in the pose box [u_lo, u_lo + u_scale]^3.
#ifndef LOCAL_SIZE
#define LOCAL_SIZE 64
#endif
layout(local_size_x = LOCAL_SIZE) in;
#include "points_jobs.glsl"
#include "points_placed.glsl"
layout(std430, binding = 9) writeonly buffer Placed { uvec4 placed[]; };
#if defined(KEYFRAMED) || defined(POSE_SLOT)
layout(std430, binding = 10) readonly buffer PoseU { float pose_u[]; };  // the job's u, or its frame
#endif
uniform uint u_items;  // work items of this dispatch (the last job's prefix + count)
uniform vec3 u_lo;
uniform float u_scale;

// this thread's work item: its job (one pose) and the vertex k of the pose's prefix; false past the last
bool pose_item(out uint j, out uvec4 job, out uint k) {
    uint g = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * uint(LOCAL_SIZE);
    if (g >= u_items) return false;
    j = find_job(g);
    job = jobs[j];
    k = g - job.w;
    return true;
}

#ifdef KEYFRAMED
struct Sample {
    uvec4 geo;
    uvec4 attr;
};
layout(std430, binding = 6) readonly buffer KVerts { Sample kverts[]; };

void main() {
    uint j, k;
    uvec4 job;
    if (!pose_item(j, job, k)) return;
    Sample s = kverts[job.z + k];
    float u = clamp(pose_u[j], 0.0, 1.0);
    vec2 a = unpackUnorm2x16(s.geo.x);
    vec2 b = unpackUnorm2x16(s.geo.y);
    vec2 c = unpackUnorm2x16(s.geo.z);
    vec3 p = mix(vec3(a, b.x), vec3(b.y, c), u);  // already in the pose box (the same box)
    vec3 n = mix(oct_decode(s.attr.z), oct_decode(s.attr.w), u);
    vec4 col = mix(unpackUnorm4x8(s.attr.x), unpackUnorm4x8(s.attr.y), u);
    placed[job.x + k] = placed_pack(p, n, col);
}
#else
#include "skinning.glsl"
#include "targets.glsl"
// per vertex (new numbering, lod/points/follow.py vorder): (position xyz float bits, normal oct),
// (colour RGBA8, joints 0 | 1 as uint16 pairs, joints 2 | 3, 0), (weights as float bits)
layout(std430, binding = 6) readonly buffer Verts { uvec4 verts[]; };

void main() {
    uint j, v;
    uvec4 job;
    if (!pose_item(j, job, v)) return;
#ifdef POSE_SLOT
    float frame = pose_u[j];
#else
    float frame = uintBitsToFloat(job.z);
#endif
    uvec4 a = verts[3u * v];
    uvec4 b = verts[3u * v + 1u];
    uvec4 w = verts[3u * v + 2u];
    vec3 bp = uintBitsToFloat(a.xyz);
    vec3 bn = oct_decode(a.w);
#ifdef MORPH_TARGETS
    targets_apply(int(v), frame, bp, bn);  // morph, then skin
#endif
    uvec4 jn = uvec4(b.y & 0xFFFFu, b.y >> 16, b.z & 0xFFFFu, b.z >> 16);
    vec4 r0, r1, r2;
#ifdef POSE_SLOT
    palette_rows(jn, uintBitsToFloat(w), int(job.z), r0, r1, r2);
#else
    skin_rows(jn, uintBitsToFloat(w), frame, r0, r1, r2);
#endif
    vec4 h = vec4(bp, 1.0);
    vec3 p = vec3(dot(r0, h), dot(r1, h), dot(r2, h));
    vec3 n = vec3(dot(r0.xyz, bn), dot(r1.xyz, bn), dot(r2.xyz, bn));
    placed[job.x + v] = placed_pack((p - u_lo) / u_scale, n, unpackUnorm4x8(b.x));
}
#endif
