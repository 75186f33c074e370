// Samples placed with the animation (render/points/follow.py, lod/points/follow.py) and the posed
// vertices they are placed from share one layout, a uvec4:
//   (position x | y as unorm16x2, z as unorm16 | 0, normal octahedral snorm16x2, colour RGBA8),
// positions in the representation's pose box (its offset and uniform scale folded into each instance's
// matrix, as for the stored samples of points_common.glsl).

// octahedral normal encoding (Meyer et al. 2010): unit vector from [-1, 1]^2
vec3 oct_decode(uint w) {
    vec2 e = unpackSnorm2x16(w);
    vec3 v = vec3(e, 1.0 - abs(e.x) - abs(e.y));
    if (v.z < 0.0) v.xy = (1.0 - abs(v.yx)) * vec2(v.x >= 0.0 ? 1.0 : -1.0, v.y >= 0.0 ? 1.0 : -1.0);
    return v;
}

// its inverse (render/points/samples.py oct_encode); a zero vector gives +z
uint oct_encode(vec3 n) {
    float l1 = abs(n.x) + abs(n.y) + abs(n.z);
    vec3 v = l1 > 1e-30 ? n / l1 : vec3(0.0, 0.0, 1.0);
    vec2 e = v.xy;
    if (v.z < 0.0) e = (1.0 - abs(v.yx)) * vec2(v.x >= 0.0 ? 1.0 : -1.0, v.y >= 0.0 ? 1.0 : -1.0);
    return packSnorm2x16(clamp(e, -1.0, 1.0));
}

vec3 placed_pos(uvec4 w) {
    return vec3(unpackUnorm2x16(w.x), unpackUnorm2x16(w.y).x);
}

void placed_at(uvec4 w, out vec3 pos, out vec3 nrm, out vec4 col) {
    pos = placed_pos(w);
    nrm = oct_decode(w.z);
    col = unpackUnorm4x8(w.w);
}

uvec4 placed_pack(vec3 pos, vec3 nrm, vec4 col) {
    vec3 q = clamp(pos, 0.0, 1.0);
    return uvec4(packUnorm2x16(q.xy), packUnorm2x16(vec2(q.z, 0.0)), oct_encode(nrm), packUnorm4x8(col));
}
