#version 430
// Vertex pass of the compute rasteriser (render/raster/frame.py): every vertex of every instance of the frame,
// transformed as the hardware path's vertex stage does (instance rows, then u_view_proj), snapped to window
// coordinates in fixed point with RS_SUBPIXEL_BITS fractional bits, pixel centres on integers (llvmpipe:
// FIXED_ORDER 8), and written with its window depth and clip outcodes to u_screen:
//   (x, y, floatBitsToInt(depth), outcodes), outcodes: 1 x < -w, 2 x > w, 4 y < -w, 8 y > w, 16 near (w <= 0 or
//   z < -w), 32 z > w.
// One work group: 8 threads x RS_VERTS_PER_THREAD consecutive vertices of one instance (a vertex job).
#ifndef RS_VERTS_PER_THREAD
#define RS_VERTS_PER_THREAD 16
#endif
layout(local_size_x = 8) in;
#include "raster_common.glsl"

layout(rgba32i, binding = 0) uniform writeonly iimage2D u_screen;
// vertex jobs: (instance, first vertex, vertices)
layout(std430, binding = 5) readonly buffer VertexJobs { uvec4 vjobs[]; };
uniform mat4 u_view_proj;
uniform ivec2 u_size;
uniform uint u_njobs;

#define RS_SUBPIXEL_BITS 8
// window coordinates are clamped to +-RS_GUARD pixels (the fixed-point values then fit 31 bits); a vertex
// there belongs to a triangle far larger than the compute threshold, which goes to the hardware path
#define RS_GUARD 1048576.0

void main() {
    uint j = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (j >= u_njobs) return;
    uvec4 job = vjobs[j];
    RsInstance r = rs_instance(job.x);
    vec2 half_size = vec2(u_size) * 0.5;
    for (uint q = 0u; q < uint(RS_VERTS_PER_THREAD); ++q) {
        uint k = q * 8u + gl_LocalInvocationID.x;
        if (k >= job.z) return;
        uint v = job.y + k;
        vec3 world = rs_point(r, rs_position(r, v));
        vec4 clip = u_view_proj * vec4(world, 1.0);
        int codes = (clip.x < -clip.w ? 1 : 0) | (clip.x > clip.w ? 2 : 0) | (clip.y < -clip.w ? 4 : 0)
                  | (clip.y > clip.w ? 8 : 0) | (!(clip.w > 0.0) || clip.z < -clip.w ? 16 : 0)
                  | (clip.z > clip.w ? 32 : 0);
        ivec4 o = ivec4(0, 0, 0, codes);
        if ((codes & 16) == 0) {
            // the viewport transform as llvmpipe's draw module does it: ndc = clip * (1 / w)
            float iw = 1.0 / clip.w;
            vec3 ndc = clip.xyz * iw;
            vec2 win = clamp(ndc.xy * half_size + half_size, -RS_GUARD, RS_GUARD);
            // pixel centres (i + 0.5) on integer multiples of 2^RS_SUBPIXEL_BITS
            o.xy = ivec2(roundEven((win - 0.5) * float(1 << RS_SUBPIXEL_BITS)));
            o.z = floatBitsToInt(ndc.z * 0.5 + 0.5);
        }
        imageStore(u_screen, rs_texel(r.screen + v), o);
    }
}
