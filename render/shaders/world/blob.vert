#version 330 core
// Blob shadow (render/world/shadows.py): one quad per agent lying on its floor
// point, instanced; i_blob = (camera-relative floor point, radius in metres).
in vec2 in_corner;      // (-1, -1) .. (1, 1)
in vec4 i_blob;

uniform mat4 u_view_proj;
uniform float u_lift;   // metres above the floor point (with a polygon offset: no z-fighting)

out vec2 v_q;

void main() {
    v_q = in_corner;
    vec3 p = i_blob.xyz + vec3(in_corner.x * i_blob.w, u_lift, in_corner.y * i_blob.w);
    gl_Position = u_view_proj * vec4(p, 1.0);
}
