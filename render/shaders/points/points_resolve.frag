#version 430
// Resolve of the compute splat (render/points/draw.py): a pixel is covered by the
// points anchored at the s x s slots at and below-left of it; the nearest
// wins. A covered pixel writes that point's colour and depth (gl_FragDepth),
// so the fixed-function depth test compares the points with the triangles
// drawn earlier in the frame.
#ifndef MARGIN
#define MARGIN 2
#endif
layout(std430, binding = 3) readonly buffer Depth { uint depth[]; };
layout(std430, binding = 4) readonly buffer Color { uint color[]; };
uniform ivec2 u_size;
uniform int u_splat;
out vec4 f_color;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    uint best = 0xFFFFFFFFu;
    uint slot = 0u;
    for (int dy = 0; dy < u_splat; ++dy) {
        for (int dx = 0; dx < u_splat; ++dx) {
            uint s = uint((p.y - dy + MARGIN) * (u_size.x + MARGIN) + p.x - dx + MARGIN);
            uint k = depth[s];
            if (k < best) {
                best = k;
                slot = s;
            }
        }
    }
    if (best == 0xFFFFFFFFu) discard;
    gl_FragDepth = uintBitsToFloat(best);
    f_color = unpackUnorm4x8(color[slot]);
}
