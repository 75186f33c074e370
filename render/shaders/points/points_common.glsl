// Shared declarations of the point-hierarchy drawer (render/points/draw.py,
// Wand & Strasser 2002, section 3): storage buffers, job lookup, attribute
// interpolation between the keyframes of a segment and lighting (as lit.frag).
//
// A sample (point or triangle-corner vertex) is 2 x 16 bytes:
//   geo = (p0.x | p0.y, p0.z | p1.x, p1.y | p1.z, unused): positions at u = 0 and
//         u = 1 as unorm16 in the representation's box, whose offset and
//         uniform scale render/points/draw.py folds into each instance's matrix,
//   attr = (colour0 RGBA8, colour1 RGBA8, normal0 octahedral snorm16x2,
//         normal1 octahedral snorm16x2).
// The splat's depth pass reads three words per point.
struct Sample {
    uvec4 geo;
    uvec4 attr;
};

// per-instance data: rows 0..2 of the camera-relative model matrix, then (u, 0, 0, 0)
layout(std430, binding = 1) readonly buffer Instances { vec4 inst[]; };
// jobs: (first sample, count, instance, exclusive prefix of counts); find_job
#include "points_jobs.glsl"
// per-instance colour words (variation, debug), as the triangle paths' i_tint (tint.glsl)
layout(std430, binding = 12) readonly buffer Tints { uvec2 tints[]; };
#include "tint.glsl"
#include "light.glsl"
// oct_decode and the placed samples of the representations that follow the animation
#include "points_placed.glsl"

vec3 inst_point(uint i, vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(inst[4u * i], h), dot(inst[4u * i + 1u], h), dot(inst[4u * i + 2u], h));
}

vec3 inst_dir(uint i, vec3 d) {
    return vec3(dot(inst[4u * i].xyz, d), dot(inst[4u * i + 1u].xyz, d), dot(inst[4u * i + 2u].xyz, d));
}

float inst_u(uint i) {
    return clamp(inst[4u * i + 3u].x, 0.0, 1.0);
}

// position at time u in [0, 1] (box units: the instance matrix maps them to the world)
vec3 sample_pos(uvec4 geo, float u) {
    vec2 a = unpackUnorm2x16(geo.x);
    vec2 b = unpackUnorm2x16(geo.y);
    vec2 c = unpackUnorm2x16(geo.z);
    return mix(vec3(a, b.x), vec3(b.y, c), u);
}

void sample_at(Sample s, float u, out vec3 pos, out vec3 nrm, out vec4 col) {
    pos = sample_pos(s.geo, u);
    nrm = mix(oct_decode(s.attr.z), oct_decode(s.attr.w), u);
    col = mix(unpackUnorm4x8(s.attr.x), unpackUnorm4x8(s.attr.y), u);
}

vec3 shade(vec3 world, vec3 normal, vec3 base) {
    return light_shade(world, normal, base, 1.0);  // point splats receive no shadow map (blobs instead)
}
