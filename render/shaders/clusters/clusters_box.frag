#version 330 core
// Occlusion-query proxy: writes are masked off; only the depth test matters.
out vec4 f_color;

void main() {
    f_color = vec4(1.0);
}
