#version 330 core
// Geomorphed cluster geometry (lod/clusters/morph.py; Friedrich, Polthier &
// Schmies §3 applied to a VDR-AM hierarchy): the clusters.vert draw, plus a
// blend of every vertex towards the vertex of a coarser ancestor cluster it
// has collapsed into (morph.glsl). i_anim.z = height of that ancestor (< 0: no
// morph), i_anim.w = blend weight. Both vertices are skinned with the
// instance's palette; weight 0 draws the fine cluster, weight 1 exactly the
// ancestor's triangles (plus degenerate ones).
#include "instance.glsl"
#include "skinning.glsl"
#include "morph.glsl"

in vec3 in_position;
in vec3 in_normal;
in vec4 in_color;
in uvec4 in_joints;
in vec4 in_weights;

uniform mat4 u_view_proj;

out vec3 v_world;   // camera-relative world position
out vec3 v_normal;
out vec4 v_color;

void main() {
    int slot = int(i_anim.y + 0.5);
    vec4 r0, r1, r2;
    palette_rows(in_joints, in_weights, slot, r0, r1, r2);
    vec4 h = vec4(in_position, 1.0);
    vec3 p = vec3(dot(r0, h), dot(r1, h), dot(r2, h));
    vec3 n = skin_normal(r0, r1, r2, in_normal);  // inverse transpose (skinning.glsl)
    vec4 color = in_color;
    morph_blend(gl_VertexID, int(floor(i_anim.z + 0.5)), clamp(i_anim.w, 0.0, 1.0), true, slot, 0.0, p, n, color);
    v_world = instance_point(p);
    v_normal = instance_dir(n);
    v_color = tint_color(color, i_tint);
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
