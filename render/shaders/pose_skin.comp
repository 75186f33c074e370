#version 430
// The pose cache's skinning pass (render/pose_cache.py): one invocation per
// (vertex, pose slot) of a window writes the vertex skinned in that pose to
// the posed-vertex buffer (posed.glsl). The slot's joint palette was blended
// once per pose (u_palette, the layout of skinning.glsl palette_rows); morph
// targets are applied first at the pose's frame coordinate (targets.glsl,
// MORPH_TARGETS); the normal goes through the inverse transpose of the blended
// matrix (skinning.glsl skin_normal) -- the same code as the per-copy draws.
#ifndef LOCAL_SIZE
#define LOCAL_SIZE 64
#endif
layout(local_size_x = LOCAL_SIZE) in;
#include "skinning.glsl"
#include "targets.glsl"

layout(std430, binding = 0) readonly buffer BindPosition { float bind_position[]; };  // 3 per vertex
layout(std430, binding = 1) readonly buffer BindNormal { float bind_normal[]; };      // 3 per vertex
layout(std430, binding = 2) readonly buffer SkinJoints { uvec4 skin_joints[]; };
layout(std430, binding = 3) readonly buffer SkinWeights { vec4 skin_weights[]; };
layout(std430, binding = 4) readonly buffer PoseFrames { float pose_frame[]; };       // per slot of the group
#define POSED_WRITE
#include "posed.glsl"

uniform int u_slot_start;  // slot of gl_GlobalInvocationID.y == 0

void main() {
    int v = int(gl_GlobalInvocationID.x);
    if (v >= u_posed_vertices) return;
    int slot = u_slot_start + int(gl_GlobalInvocationID.y);
    vec3 bp = vec3(bind_position[3 * v], bind_position[3 * v + 1], bind_position[3 * v + 2]);
    vec3 bn = vec3(bind_normal[3 * v], bind_normal[3 * v + 1], bind_normal[3 * v + 2]);
#ifdef MORPH_TARGETS
    targets_apply(v, pose_frame[slot], bp, bn);  // morph, then skin
#endif
    vec4 r0, r1, r2;
    palette_rows(skin_joints[v], skin_weights[v], slot, r0, r1, r2);
    vec4 h = vec4(bp, 1.0);
    posed_store(slot, v, vec3(dot(r0, h), dot(r1, h), dot(r2, h)), skin_normal(r0, r1, r2, bn));
}
