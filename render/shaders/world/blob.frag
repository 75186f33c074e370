#version 330 core
// A soft dark disc: opacity u_blob.x at the centre, falling off smoothly from
// u_blob.y (fraction of the radius) to 0 at the rim; alpha-blended over the ground.
in vec2 v_q;

uniform vec2 u_blob;    // (opacity at the centre, radius fraction where the falloff starts)

out vec4 f_color;

void main() {
    float a = u_blob.x * (1.0 - smoothstep(u_blob.y, 1.0, length(v_q)));
    if (a <= 0.0) discard;
    f_color = vec4(0.0, 0.0, 0.0, a);
}
