// Per-instance colour variation and debug colouring (render/tint.py), shared by
// every draw path (full detail, LOD chains, clusters, point triangles, GL
// points and the compute splat's colour pass), so a LOD switch never changes
// a colour. One instance word pair w = (variation, debug), uint32 each:
//   variation: bytes (b0, b1, b2, mode): mode 0 = unchanged; mode 1 = HSV
//     shift: hue += (b0 - 128) / 256 turns, saturation *= b1 / 128,
//     value *= b2 / 128; mode 2 = palette: the colour becomes (b0, b1, b2) / 255.
//     Applied with the weight of the vertex colour's alpha (the character's
//     variation regions: 1 = varies, 0 = kept, e.g. skin).
//   debug: RGBA8 (r, g, b, weight) mixed in after the variation
//     (lod/debug_colors.py; weight 0 = true colours).
// HSV after Sam Hocevar's branchless conversion; the 1e-10 guards keep grey
// and black (zero chroma, zero value) finite: their hue is 0 and a hue shift
// leaves them unchanged.

vec4 tint_bytes(uint w) {
    return vec4(float(w & 255u), float((w >> 8) & 255u), float((w >> 16) & 255u), float(w >> 24));
}

vec3 tint_rgb_to_hsv(vec3 c) {
    vec4 K = vec4(0.0, -1.0 / 3.0, 2.0 / 3.0, -1.0);
    vec4 p = mix(vec4(c.bg, K.wz), vec4(c.gb, K.xy), step(c.b, c.g));
    vec4 q = mix(vec4(p.xyw, c.r), vec4(c.r, p.yzx), step(p.x, c.r));
    float d = q.x - min(q.w, q.y);
    float e = 1.0e-10;
    return vec3(abs(q.z + (q.w - q.y) / (6.0 * d + e)), d / (q.x + e), q.x);
}

vec3 tint_hsv_to_rgb(vec3 c) {
    vec3 p = abs(fract(c.xxx + vec3(1.0, 2.0 / 3.0, 1.0 / 3.0)) * 6.0 - 3.0);
    return c.z * mix(vec3(1.0), clamp(p - 1.0, 0.0, 1.0), c.y);
}

// The colour of a vertex (rgb, a = variation weight) of the instance with words w.
vec4 tint_color(vec4 color, uvec2 w) {
    vec3 rgb = clamp(color.rgb, 0.0, 1.0);
    vec4 v = tint_bytes(w.x);
    float mask = clamp(color.a, 0.0, 1.0);
    if (v.w == 1.0) {
        vec3 hsv = tint_rgb_to_hsv(rgb);
        hsv.x = fract(hsv.x + (v.x - 128.0) / 256.0);
        hsv.y = clamp(hsv.y * v.y / 128.0, 0.0, 1.0);
        hsv.z = clamp(hsv.z * v.z / 128.0, 0.0, 1.0);
        rgb = mix(rgb, tint_hsv_to_rgb(hsv), mask);
    } else if (v.w == 2.0) {
        rgb = mix(rgb, v.xyz / 255.0, mask);
    }
    vec4 d = tint_bytes(w.y) / 255.0;
    return vec4(mix(rgb, d.rgb, d.a), 1.0);
}
