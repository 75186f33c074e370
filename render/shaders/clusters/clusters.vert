#version 330 core
// Cluster geometry of a VDR-AM hierarchy (render/clusters/draw.py): the skinned
// draw of skinned.vert (palette path, skinning.glsl), except that an instance
// finds its palette block through i_anim.y (its slot in this frame's palette)
// rather than gl_InstanceID, because the clusters are drawn by
// multi-draw-indirect commands with a base instance, which gl_InstanceID does
// not include.
#include "instance.glsl"
#include "skinning.glsl"

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
    palette_rows(in_joints, in_weights, int(i_anim.y + 0.5), r0, r1, r2);
    vec4 h = vec4(in_position, 1.0);
    vec3 p = vec3(dot(r0, h), dot(r1, h), dot(r2, h));
    vec3 n = skin_normal(r0, r1, r2, in_normal);  // inverse transpose (skinning.glsl)
    v_world = instance_point(p);
    v_normal = instance_dir(n);
    v_color = tint_color(in_color, i_tint);
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
