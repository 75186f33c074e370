#version 430
// Resolve of the far tier's splats (render/far/draw.py): a pixel the far agents reached takes their
// alpha-weighted mean colour C with the coverage of independent agents, a = 1 - prod(1 - alpha) =
// 1 - exp(-sum(-log(1 - alpha))), over the frame darkened by their blob shadows' joint opacity s (likewise):
// out = C a + dst (1 - a)(1 - s), premultiplied (blend ONE, ONE_MINUS_SRC_ALPHA), at their nearest depth
// (gl_FragDepth: the fixed-function test keeps it behind nearer surfaces). It resets the pixel's
// accumulators for the next frame.
#define SCALE 4096.0
layout(std430, binding = 3) buffer Accum { uint acc[]; };
uniform ivec2 u_size;
out vec4 f_color;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    uint k = uint(p.y * u_size.x + p.x) * 7u;
    uint w = acc[k + 4u];
    uint ws = acc[k + 6u];
    if (w == 0u && ws == 0u) discard;
    float depth = uintBitsToFloat(acc[k]);
    vec3 c = w > 0u ? vec3(float(acc[k + 1u]), float(acc[k + 2u]), float(acc[k + 3u])) / float(w) : vec3(0.0);
    float cover = 1.0 - exp(-float(acc[k + 5u]) / SCALE);
    float shade = 1.0 - exp(-float(ws) / SCALE);
    acc[k] = 0xFFFFFFFFu;
    acc[k + 1u] = 0u;
    acc[k + 2u] = 0u;
    acc[k + 3u] = 0u;
    acc[k + 4u] = 0u;
    acc[k + 5u] = 0u;
    acc[k + 6u] = 0u;
    gl_FragDepth = depth;
    f_color = vec4(c * cover, 1.0 - (1.0 - cover) * (1.0 - shade));
}
