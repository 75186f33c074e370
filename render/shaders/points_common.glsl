// Shared declarations of the point-hierarchy drawer (render/points.py,
// Wand & Strasser 2002, section 3): storage buffers, job lookup, attribute
// interpolation between the keyframes of a segment and lighting (as lit.frag).
//
// A sample (point or triangle-corner vertex) is 3 x 16 bytes:
//   p0 = (position at u = 0, normal0.z), p1 = (position at u = 1, normal1.z),
//   attr = (colour0 RGBA8, colour1 RGBA8, normal0.xy snorm16x2, normal1.xy snorm16x2).
struct Sample {
    vec4 p0;
    vec4 p1;
    uvec4 attr;
};

// per-instance data: rows 0..2 of the camera-relative model matrix, then (u, 0, 0, 0)
layout(std430, binding = 1) readonly buffer Instances { vec4 inst[]; };
// jobs: (first sample, count, instance, exclusive prefix of counts)
layout(std430, binding = 2) readonly buffer Jobs { uvec4 jobs[]; };

uniform uint u_njobs;
uniform vec3 u_sun;
uniform float u_ambient;

// the job holding work item g (largest j with jobs[j].w <= g)
uint find_job(uint g) {
    uint lo = 0u;
    uint hi = u_njobs - 1u;
    while (lo < hi) {
        uint mid = (lo + hi + 1u) >> 1;
        if (jobs[mid].w <= g) lo = mid; else hi = mid - 1u;
    }
    return lo;
}

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

void sample_at(Sample s, float u, out vec3 pos, out vec3 nrm, out vec4 col) {
    pos = mix(s.p0.xyz, s.p1.xyz, u);
    vec3 n0 = vec3(unpackSnorm2x16(s.attr.z), s.p0.w);
    vec3 n1 = vec3(unpackSnorm2x16(s.attr.w), s.p1.w);
    nrm = mix(n0, n1, u);
    col = mix(unpackUnorm4x8(s.attr.x), unpackUnorm4x8(s.attr.y), u);
}

vec3 shade(vec3 world, vec3 normal, vec3 base) {
    float ln = dot(normal, normal);
    vec3 n = ln > 1e-20 ? normal * inversesqrt(ln) : vec3(0.0, 1.0, 0.0);
    float lv = dot(world, world);
    vec3 head = lv > 1e-20 ? -world * inversesqrt(lv) : vec3(0.0, 0.0, 1.0);
    float diffuse = 0.55 * abs(dot(n, u_sun)) + 0.35 * abs(dot(n, head));
    return base * (u_ambient + diffuse);
}
