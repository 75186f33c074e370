#version 330 core
// Per-frame palette pre-pass (transform feedback, one point per matrix row):
// vertex v of instance i writes row v % 3 of joint v / 3 blended between the
// two baked frames around the instance's frame coordinate.
#include "skinning.glsl"

in vec4 i_anim;

out vec4 v_row;

void main() {
    v_row = baked_row(gl_VertexID / 3, gl_VertexID % 3, i_anim.x);
}
