#version 430
// Resolve of the compute splat (render/points/draw.py): a pixel is covered by the
// points anchored at the s x s slots at and below-left of it. NEAREST: the
// nearest wins and the pixel takes its colour. Otherwise the anchors whose
// nearest lies within the depth tolerance of the pixel's nearest (eye depth
// w <= w_min (1 + u_tol)) add their accumulated colour x weight and weight
// (points_splat.glsl), and the pixel takes the weighted mean. A covered pixel
// writes the nearest depth (gl_FragDepth), so the fixed-function depth test
// compares the points with the triangles drawn earlier in the frame.
#ifndef MARGIN
#define MARGIN 2
#endif
layout(std430, binding = 3) readonly buffer Depth { uint depth[]; };
layout(std430, binding = 4) readonly buffer Color { uint color[]; };
uniform ivec2 u_size;
uniform int u_splat;
#ifndef NEAREST
uniform vec2 u_depth_ab;  // as points_splat.glsl
uniform float u_tol;
#endif
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
#ifdef NEAREST
    f_color = unpackUnorm4x8(color[slot]);
#else
    float far_w = u_depth_ab.y / (u_depth_ab.x - (2.0 * uintBitsToFloat(best) - 1.0)) * (1.0 + u_tol);
    uvec4 sum = uvec4(0u);
    for (int dy = 0; dy < u_splat; ++dy) {
        for (int dx = 0; dx < u_splat; ++dx) {
            uint s = uint((p.y - dy + MARGIN) * (u_size.x + MARGIN) + p.x - dx + MARGIN);
            uint k = depth[s];
            if (k == 0xFFFFFFFFu) continue;
            float w = u_depth_ab.y / (u_depth_ab.x - (2.0 * uintBitsToFloat(k) - 1.0));
            if (s == slot || w <= far_w) {
                sum += uvec4(color[4u * s], color[4u * s + 1u], color[4u * s + 2u], color[4u * s + 3u]);
            }
        }
    }
    // every covered anchor holds its nearest point (weight >= 1): sum.w > 0
    f_color = vec4(vec3(sum.rgb) / (255.0 * float(max(sum.w, 1u))), 1.0);
#endif
}
