#version 330 core
// HUD text and panels: quads given in window pixels (origin top-left, y down).
uniform vec2 u_screen;      // framebuffer size, pixels

in vec2 in_pos;             // pixels
in vec2 in_uv;              // font atlas texture coordinates
in vec4 in_color;           // straight (non-premultiplied) RGBA

out vec2 v_uv;
out vec4 v_color;

void main() {
    vec2 ndc = vec2(in_pos.x / u_screen.x * 2.0 - 1.0, 1.0 - in_pos.y / u_screen.y * 2.0);
    gl_Position = vec4(ndc, 0.0, 1.0);
    v_uv = in_uv;
    v_color = in_color;
}
