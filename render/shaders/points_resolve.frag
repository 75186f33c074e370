#version 430
// Resolve of the compute splat: a covered pixel writes its colour and its
// depth (gl_FragDepth), so the fixed-function depth test compares the points
// with the triangles drawn earlier in the frame.
layout(std430, binding = 3) readonly buffer Depth { uint depth[]; };
layout(std430, binding = 4) readonly buffer Color { uint color[]; };
uniform ivec2 u_size;
out vec4 f_color;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    uint pix = uint(p.y * u_size.x + p.x);
    uint key = depth[pix];
    if (key == 0xFFFFFFFFu) discard;
    gl_FragDepth = uintBitsToFloat(key);
    f_color = unpackUnorm4x8(color[pix]);
}
