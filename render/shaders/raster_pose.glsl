#version 430
// Posed vertices of skinned instances for the compute rasteriser (render/raster/poses.py): the adapter
// that stands for the pose cache until it lands. Every vertex of an instance is skinned from the baked joint
// table at the instance's frame coordinate, as skinned_direct.vert does (skinning.glsl skin_rows; morph
// targets first with MORPH_TARGETS, targets.glsl), and written in the model frame to the posed texture
// (raster_common.glsl layout: (p, n.x), (n.y, n.z, 0, 0)). One work group: 8 threads x
// RS_VERTS_PER_THREAD consecutive vertices of one instance (one pose slot per instance).
#ifndef RS_VERTS_PER_THREAD
#define RS_VERTS_PER_THREAD 16
#endif
layout(local_size_x = 8) in;
#include "raster_common.glsl"
#include "skinning.glsl"
#include "targets.glsl"

layout(rgba32f, binding = 1) uniform writeonly image2D u_posed_out;
// (instance, first vertex, vertices, frame coordinate as float bits)
layout(std430, binding = 5) readonly buffer PoseJobs { uvec4 pjobs[]; };
uniform usampler2D u_skin;  // 2 texels per vertex of the mesh: joints, weights (float bits)
uniform uint u_njobs;

void main() {
    uint j = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (j >= u_njobs) return;
    uvec4 job = pjobs[j];
    RsInstance r = rs_instance(job.x);
    float frame = uintBitsToFloat(job.w);
    for (uint q = 0u; q < uint(RS_VERTS_PER_THREAD); ++q) {
        uint k = q * 8u + gl_LocalInvocationID.x;
        if (k >= job.z) return;
        uint v = job.y + k;
        vec3 bp, bn;
        vec4 col;
        rs_record(r.mesh + v, bp, bn, col);
        uvec4 jn = texelFetch(u_skin, rs_texel(2u * v), 0);
        vec4 wt = uintBitsToFloat(texelFetch(u_skin, rs_texel(2u * v + 1u), 0));
        vec4 r0, r1, r2;
        skin_rows(jn, wt, frame, r0, r1, r2);
#ifdef MORPH_TARGETS
        targets_apply(int(v), frame, bp, bn);  // morph, then skin
#endif
        vec4 h = vec4(bp, 1.0);
        vec3 p = vec3(dot(r0, h), dot(r1, h), dot(r2, h));
        vec3 n = vec3(dot(r0.xyz, bn), dot(r1.xyz, bn), dot(r2.xyz, bn));
        uint t = (r.posed + v) * RS_POSED;
        imageStore(u_posed_out, rs_texel(t), vec4(p, n.x));
        imageStore(u_posed_out, rs_texel(t + 1u), vec4(n.yz, 0.0, 0.0));
    }
}
