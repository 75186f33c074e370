#version 330 core
// HUD: glyph coverage (red channel of the text texture, row 0 = top line)
// mixes the panel colour with the text colour; straight alpha, blended over the frame.
uniform sampler2D u_text;
uniform vec4 u_color;       // text RGBA
uniform vec4 u_panel;       // panel RGBA (alpha 0: no panel)

in vec2 v_uv;

out vec4 f_color;

void main() {
    float coverage = texture(u_text, v_uv).r;
    f_color = mix(u_panel, u_color, coverage);
}
