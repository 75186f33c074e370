#version 430
// Posed vertices of skinned instances for the compute rasteriser (render/raster/frame.py Raster._gather):
// copied from the pose cache (render/poses/cache.py, posed.glsl), where each distinct pose of the frame was
// skinned once (poses/pose_skin.comp), into the rasteriser's posed table (raster_common.glsl layout:
// (p, n.x), (n.y, n.z, 0, 0)). No pose is evaluated here. One work group: 8 threads x RS_VERTS_PER_THREAD
// consecutive vertices of one pose slot's vertex range.
#ifndef RS_VERTS_PER_THREAD
#define RS_VERTS_PER_THREAD 16
#endif
layout(local_size_x = 8) in;
#include "raster_common.glsl"
#include "posed.glsl"

layout(rgba32f, binding = 1) uniform writeonly image2D u_posed_out;
// (instance standing for the slot, first vertex, vertices, pose-cache slot)
layout(std430, binding = 5) readonly buffer PoseJobs { uvec4 pjobs[]; };
uniform uint u_njobs;

void main() {
    uint j = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (j >= u_njobs) return;
    uvec4 job = pjobs[j];
    RsInstance r = rs_instance(job.x);
    int slot = int(job.w);
    for (uint q = 0u; q < uint(RS_VERTS_PER_THREAD); ++q) {
        uint k = q * 8u + gl_LocalInvocationID.x;
        if (k >= job.z) return;
        uint v = job.y + k;
        vec3 p;
        vec3 n;
        posed_vertex(slot, int(v), p, n);
        uint t = (r.posed + v) * RS_POSED;
        imageStore(u_posed_out, rs_texel(t), vec4(p, n.x));
        imageStore(u_posed_out, rs_texel(t + 1u), vec4(n.yz, 0.0, 0.0));
    }
}
