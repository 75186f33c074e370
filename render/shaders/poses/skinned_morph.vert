#version 330 core
// Geomorphed LOD chain level (lod/chains/mode.py TriangleDrawBatch.morph),
// palette path: the skinned.vert draw of one level with every vertex blended
// by u_morph_weight towards the vertex it has become in level u_morph_level
// (morph.glsl; the batch's instances share both).
#include "instance.glsl"
#include "skinning.glsl"
#include "targets.glsl"
#include "morph.glsl"

in vec3 in_position;
in vec3 in_normal;
in vec4 in_color;
in uvec4 in_joints;
in vec4 in_weights;

uniform mat4 u_view_proj;
uniform int u_morph_level;
uniform float u_morph_weight;

out vec3 v_world;   // camera-relative world position
out vec3 v_normal;
out vec4 v_color;

void main() {
    vec4 r0, r1, r2;
    palette_rows(in_joints, in_weights, palette_index(), r0, r1, r2);
    vec3 bp = in_position;
    vec3 bn = in_normal;
#ifdef MORPH_TARGETS
    targets_apply(gl_VertexID, i_anim.x, bp, bn);  // morph, then skin
#endif
    vec4 h = vec4(bp, 1.0);
    vec3 p = vec3(dot(r0, h), dot(r1, h), dot(r2, h));
    vec3 n = skin_normal(r0, r1, r2, bn);  // inverse transpose (skinning.glsl)
    vec4 color = in_color;
    morph_blend(gl_VertexID, u_morph_level, clamp(u_morph_weight, 0.0, 1.0), true, palette_index(), 0.0, p, n, color);
    v_world = instance_point(p);
    v_normal = instance_dir(n);
    v_color = tint_color(color, i_tint);
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
