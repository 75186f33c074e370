#version 430
// Geometry of the splat resolve pass (render/points/draw.py): the pixel rectangles
// (in NDC) whose footprints reach anchor tiles the depth pass filled, or one
// full-screen triangle when most of the screen is touched.
in vec2 in_pos;

void main() {
    gl_Position = vec4(in_pos, 0.0, 1.0);
}
