// Linear blend skinning from baked joint matrices (shared by the draw and the
// transform-feedback capture programs).
//
// u_joints: RGBA32F texture, one row per baked frame, three texels per joint
// (rows 0..2 of the 3x4 skinning matrix). The frame coordinate is fractional:
// the matrices of the two neighbouring frames are blended linearly, which for
// LBS equals blending the two skinned positions, so bounds taken at baked
// frames contain every rendered pose.
uniform sampler2D u_joints;

void skin_rows(uvec4 joints, vec4 weights, float frame, out vec4 r0, out vec4 r1, out vec4 r2) {
    int last = textureSize(u_joints, 0).y - 1;
    float ff = floor(frame);
    float a = frame - ff;
    int f0 = clamp(int(ff), 0, last);
    int f1 = min(f0 + 1, last);
    r0 = vec4(0.0);
    r1 = vec4(0.0);
    r2 = vec4(0.0);
    for (int k = 0; k < 4; ++k) {
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
