#version 330 core
// HUD: one quad given in window pixels (origin top-left, y down).
uniform vec2 u_screen;      // framebuffer size, pixels

in vec2 in_pos;             // pixels
in vec2 in_uv;              // text texture coordinates, v = 0 at the text's top row

out vec2 v_uv;

void main() {
    vec2 ndc = vec2(in_pos.x / u_screen.x * 2.0 - 1.0, 1.0 - in_pos.y / u_screen.y * 2.0);
    gl_Position = vec4(ndc, 0.0, 1.0);
    v_uv = in_uv;
}
