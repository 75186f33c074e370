// Linear blend skinning from baked joint matrices (shared by the draw, the
// palette and the transform-feedback capture programs).
//
// u_joints: RGBA32F texture, one row per baked frame, three texels per joint
// (rows 0..2 of the 3x4 skinning matrix). The frame coordinate is fractional:
// the matrices of the two neighbouring frames are blended linearly, which for
// LBS equals blending the two skinned positions, so bounds taken at baked
// frames contain every rendered pose.
uniform sampler2D u_joints;

// Influences read per vertex: 4, or fewer when the program is compiled for a mesh
// whose vertices have at most 1, 2 or 3 non-zero weights, packed first
// (render/vertex_format.py compact_influences: the same terms in the same order).
#if defined(SKIN_INFLUENCES_1)
const int SKIN_INFLUENCES = 1;
#elif defined(SKIN_INFLUENCES_2)
const int SKIN_INFLUENCES = 2;
#elif defined(SKIN_INFLUENCES_3)
const int SKIN_INFLUENCES = 3;
#else
const int SKIN_INFLUENCES = 4;
#endif

// Frame pair and blend factor of a fractional frame coordinate.
void frame_pair(float frame, out int f0, out int f1, out float a) {
    int last = textureSize(u_joints, 0).y - 1;
    float ff = floor(frame);
    a = frame - ff;
    f0 = clamp(int(ff), 0, last);
    f1 = min(f0 + 1, last);
}

// Row r (0..2) of joint j's skinning matrix at a fractional frame.
vec4 baked_row(int j, int r, float frame) {
    int f0, f1;
    float a;
    frame_pair(frame, f0, f1, a);
    int x = 3 * j + r;
    return mix(texelFetch(u_joints, ivec2(x, f0), 0), texelFetch(u_joints, ivec2(x, f1), 0), a);
}

// Normal of a skinned vertex: the bind normal n through the inverse transpose
// of the blended matrix's linear part A (rows r0..r2), computed as its cofactor
// matrix times sign(det A) (columns: cross products of A's columns), which stays
// finite where A is singular; unit length, the bind normal where the cofactor
// vanishes (+Y where that does too). The CPU reference is sim/skinning.py.
vec3 skin_normal(vec4 r0, vec4 r1, vec4 r2, vec3 n) {
    vec3 a0 = vec3(r0.x, r1.x, r2.x);
    vec3 a1 = vec3(r0.y, r1.y, r2.y);
    vec3 a2 = vec3(r0.z, r1.z, r2.z);
    vec3 c0 = cross(a1, a2);
    vec3 c1 = cross(a2, a0);
    vec3 c2 = cross(a0, a1);
    float det = dot(a0, c0);
    vec3 o = (det > 0.0 ? 1.0 : (det < 0.0 ? -1.0 : 0.0)) * (c0 * n.x + c1 * n.y + c2 * n.z);
    float lo = dot(o, o);
    if (lo > 1e-30) return o * inversesqrt(lo);
    float ln = dot(n, n);
    return ln > 1e-30 ? n * inversesqrt(ln) : vec3(0.0, 1.0, 0.0);
}

// Direct path: blend the matrices of both frames for every influence
// (24 texel fetches for 4 influences).
void skin_rows(uvec4 joints, vec4 weights, float frame, out vec4 r0, out vec4 r1, out vec4 r2) {
    int f0, f1;
    float a;
    frame_pair(frame, f0, f1, a);
    r0 = vec4(0.0);
    r1 = vec4(0.0);
    r2 = vec4(0.0);
    for (int k = 0; k < SKIN_INFLUENCES; ++k) {
        float w = weights[k];
        if (w == 0.0) continue;
        int x = 3 * int(joints[k]);
        float w0 = w * (1.0 - a);
        float w1 = w * a;
        r0 += w0 * texelFetch(u_joints, ivec2(x, f0), 0) + w1 * texelFetch(u_joints, ivec2(x, f1), 0);
        r1 += w0 * texelFetch(u_joints, ivec2(x + 1, f0), 0) + w1 * texelFetch(u_joints, ivec2(x + 1, f1), 0);
        r2 += w0 * texelFetch(u_joints, ivec2(x + 2, f0), 0) + w1 * texelFetch(u_joints, ivec2(x + 2, f1), 0);
    }
}

// Palette path: a per-frame pre-pass (palette.vert) has written every
// instance's frame-blended matrices into u_palette (RGBA32F, width a multiple
// of 3; instance i of the batch starts at texel u_palette_base + i * 3 * J),
// so a vertex reads 3 texels per influence and blends nothing.
uniform sampler2D u_palette;
uniform int u_palette_base;
uniform int u_palette_stride;  // 3 * J

void palette_rows(uvec4 joints, vec4 weights, int instance, out vec4 r0, out vec4 r1, out vec4 r2) {
    // Integer division is scalar on a CPU rasteriser (llvmpipe): locate the
    // instance's block once per vertex with a float division plus an exact
    // integer correction, and wrap each influence with a compare instead.
    int width = textureSize(u_palette, 0).x;
    int t0 = u_palette_base + instance * u_palette_stride;
    int y0 = int(float(t0) / float(width));
    int x0 = t0 - y0 * width;
    if (x0 < 0) { y0 -= 1; x0 += width; }
    else if (x0 >= width) { y0 += 1; x0 -= width; }
    r0 = vec4(0.0);
    r1 = vec4(0.0);
    r2 = vec4(0.0);
    for (int k = 0; k < SKIN_INFLUENCES; ++k) {
        float w = weights[k];
        if (w == 0.0) continue;
        ivec2 p = ivec2(x0 + 3 * int(joints[k]), y0);
        if (p.x >= width) { p.x -= width; p.y += 1; }
        r0 += w * texelFetch(u_palette, p, 0);
        r1 += w * texelFetch(u_palette, p + ivec2(1, 0), 0);
        r2 += w * texelFetch(u_palette, p + ivec2(2, 0), 0);
    }
}
