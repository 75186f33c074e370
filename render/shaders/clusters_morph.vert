#version 330 core
// Geomorphed cluster geometry (lod/cluster_morph.py; Friedrich, Polthier &
// Schmies §3 applied to a VDR-AM hierarchy): the clusters.vert draw, plus a
// blend of every vertex towards the vertex of a coarser ancestor cluster it
// has collapsed into.
//
// i_anim.z = height of that ancestor (< 0: no morph), i_anim.w = blend weight.
// The vertex follows its collapse chain (u_morph_i texel 0: next vertex, height
// of the cluster that removes it) while that cluster is no higher than the
// ancestor; the target's attributes come from u_morph_f (position, normal,
// colour, weights) and u_morph_i texel 1 (joints), and both are skinned with
// the instance's palette. Weight 0 draws the fine cluster, weight 1 exactly the
// ancestor's triangles (plus degenerate ones).
#include "instance.glsl"
#include "skinning.glsl"

in vec3 in_position;
in vec3 in_normal;
in vec4 in_color;
in uvec4 in_joints;
in vec4 in_weights;

uniform mat4 u_view_proj;
uniform isampler2D u_morph_i;  // 2 texels per vertex: (next, removed-at height, 0, 0), joints
uniform sampler2D u_morph_f;   // 4 texels per vertex: position, normal, colour, weights

// Morph chains are at most the hierarchy's height; the bound only guards a corrupt table.
const int MAX_CHAIN = 64;
// texture width 4096 = 2^12: texel t sits at (t & 4095, t >> 12)
ivec2 texel(int t) { return ivec2(t & 4095, t >> 12); }

out vec3 v_world;   // camera-relative world position
out vec3 v_normal;
out vec4 v_color;

void main() {
    int slot = int(i_anim.y + 0.5);
    vec4 r0, r1, r2;
    palette_rows(in_joints, in_weights, slot, r0, r1, r2);
    vec4 h = vec4(in_position, 1.0);
    vec3 p = vec3(dot(r0, h), dot(r1, h), dot(r2, h));
    vec3 n = vec3(dot(r0.xyz, in_normal), dot(r1.xyz, in_normal), dot(r2.xyz, in_normal));
    vec4 color = in_color;
    int target_height = int(floor(i_anim.z + 0.5));
    float w = clamp(i_anim.w, 0.0, 1.0);
    if (target_height >= 0 && w > 0.0) {
        int x = gl_VertexID;
        for (int s = 0; s < MAX_CHAIN; ++s) {
            ivec4 m = texelFetch(u_morph_i, texel(2 * x), 0);
            if (m.y > target_height) break;
            x = m.x;
        }
        if (x != gl_VertexID) {
            vec4 tp = texelFetch(u_morph_f, texel(4 * x), 0);
            vec4 tn = texelFetch(u_morph_f, texel(4 * x + 1), 0);
            vec4 tc = texelFetch(u_morph_f, texel(4 * x + 2), 0);
            vec4 tw = texelFetch(u_morph_f, texel(4 * x + 3), 0);
            uvec4 tj = uvec4(texelFetch(u_morph_i, texel(2 * x + 1), 0));
            vec4 q0, q1, q2;
            palette_rows(tj, tw, slot, q0, q1, q2);
            vec4 th = vec4(tp.xyz, 1.0);
            p = mix(p, vec3(dot(q0, th), dot(q1, th), dot(q2, th)), w);
            n = mix(n, vec3(dot(q0.xyz, tn.xyz), dot(q1.xyz, tn.xyz), dot(q2.xyz, tn.xyz)), w);
            color = mix(color, tc, w);
        }
    }
    v_world = instance_point(p);
    v_normal = instance_dir(n);
    v_color = color;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
