#version 330 core
// Occlusion-query proxy of render/clusters/draw.py (VDR-AM §5.2): box corners already
// in camera-relative world space; drawn with colour and depth writes off.
in vec3 in_position;
uniform mat4 u_view_proj;

void main() {
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
