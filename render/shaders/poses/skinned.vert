#version 330 core
// Skinned draw, palette path (see skinning.glsl); skinned_direct.vert blends
// the two baked frames per vertex instead.
#include "instance.glsl"
#include "skinning.glsl"
#include "targets.glsl"

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
    v_world = instance_point(p);
    v_normal = instance_dir(n);
    v_color = tint_color(in_color, i_tint);
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
