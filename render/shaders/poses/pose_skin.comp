#version 430
// The pose cache's skinning pass (render/poses/cache.py): one invocation per
// (vertex, pose slot) of a window writes the vertex skinned in that pose to
// the posed-vertex textures (posed.glsl). The slot's joint palette was blended
// once per pose (u_palette, the layout of skinning.glsl palette_rows, or the uniform block PosePalettes); morph
// targets are applied first at the pose's frame coordinate (targets.glsl,
// MORPH_TARGETS); the normal goes through the inverse transpose of the blended
// matrix (skinning.glsl skin_normal) -- the code of the per-copy draws.
// The mesh is read from two textures POSED_WIDTH = 4096 wide (texelFetch:
// llvmpipe scalarises per-lane storage-buffer loads): u_bind (RGBA32F, 3 texels
// per vertex: (position, 1), (normal, 0), weights) and u_skin_joints (RGBA32UI,
// 1 texel per vertex).
#ifndef LOCAL_SIZE
#define LOCAL_SIZE 64
#endif
layout(local_size_x = LOCAL_SIZE) in;
#include "skinning.glsl"
#include "targets.glsl"

uniform sampler2D u_bind;
uniform usampler2D u_skin_joints;
layout(std430, binding = 4) readonly buffer PoseFrames { float pose_frame[]; };  // per slot of the group
#define POSED_WRITE
#include "posed.glsl"

uniform int u_slot_start;  // slot of gl_GlobalInvocationID.y == 0

#ifdef PALETTE_UBO
// The palettes of the dispatch's slots as a uniform block (llvmpipe gathers from it faster than it fetches texels:
// 1.3x on the whole pass, render/poses/cache.py): slot s's joint j row r is ubo_palette[(s - u_ubo_first) * 3J + 3j + r].
layout(std140, binding = 0) uniform PosePalettes { vec4 ubo_palette[PALETTE_UBO]; };
uniform int u_ubo_first;  // slot of ubo_palette[0]

void pose_rows(uvec4 joints, vec4 weights, int slot, out vec4 r0, out vec4 r1, out vec4 r2) {
    int base = (slot - u_ubo_first) * u_palette_stride;
    r0 = vec4(0.0);
    r1 = vec4(0.0);
    r2 = vec4(0.0);
    for (int k = 0; k < SKIN_INFLUENCES; ++k) {
        float w = weights[k];
        if (w == 0.0) continue;
        int t = base + 3 * int(joints[k]);
        r0 += w * ubo_palette[t];
        r1 += w * ubo_palette[t + 1];
        r2 += w * ubo_palette[t + 2];
    }
}
#else
void pose_rows(uvec4 joints, vec4 weights, int slot, out vec4 r0, out vec4 r1, out vec4 r2) {
    palette_rows(joints, weights, slot, r0, r1, r2);
}
#endif

ivec2 mesh_texel(int t) { return ivec2(t & 4095, t >> 12); }

void main() {
    int v = int(gl_GlobalInvocationID.x);
    if (v >= u_posed_vertices) return;
    int slot = u_slot_start + int(gl_GlobalInvocationID.y);
    vec3 bp = texelFetch(u_bind, mesh_texel(3 * v), 0).xyz;
    vec3 bn = texelFetch(u_bind, mesh_texel(3 * v + 1), 0).xyz;
    vec4 weights = texelFetch(u_bind, mesh_texel(3 * v + 2), 0);
    uvec4 joints = texelFetch(u_skin_joints, mesh_texel(v), 0);
#ifdef MORPH_TARGETS
    targets_apply(v, pose_frame[slot], bp, bn);  // morph, then skin
#endif
    vec4 r0, r1, r2;
    pose_rows(joints, weights, slot, r0, r1, r2);
    vec4 h = vec4(bp, 1.0);
    posed_store(slot, v, vec3(dot(r0, h), dot(r1, h), dot(r2, h)), skin_normal(r0, r1, r2, bn));
}
