// Morph targets of a skinned mesh (glTF 2.0 §3.7.2.2), blended BEFORE
// skinning (skin ∘ morph; CPU reference sim/skinning.py skin_morph). Compiled
// only into the MORPH_TARGETS variants of the skinned programs, so a mesh
// without morph targets runs the plain shader. Include after skinning.glsl.
// Tables (render/poses/targets.py, lod/full/targets.py TargetTable), the first two
// TARGETS_WIDTH = 4096 texels wide (texel t at (t & 4095, t >> 12)):
//   u_targets_index  (RG32I):  1 texel per vertex: first entry, entry count;
//   u_targets_delta  (RGBA32F): 2 texels per entry: (position delta, target
//                               column), (normal delta, 0);
//   u_targets_weight (R32F):   one row per baked frame (the rows of u_joints),
//                               one column per target: weight - default weight.
#ifdef MORPH_TARGETS
uniform isampler2D u_targets_index;
uniform sampler2D u_targets_delta;
uniform sampler2D u_targets_weight;

ivec2 targets_texel(int t) { return ivec2(t & 4095, t >> 12); }

// Move bind-pose vertex v (position p, normal n) by the targets at the
// fractional baked frame ``frame``: the weights of the two neighbouring frames
// are blended linearly, as the joint matrices are (skinning.glsl frame_pair).
// The normal is renormalised (glTF §3.7.2.2; sim.skinning.morph) whether
// or not a target moves it (targets folded into the bind pose leave bind
// normals of any length), keeping the unmorphed one where the sum vanishes.
void targets_apply(int v, float frame, inout vec3 p, inout vec3 n) {
    ivec2 fc = texelFetch(u_targets_index, targets_texel(v), 0).xy;
    int f0, f1;
    float a;
    frame_pair(frame, f0, f1, a);
    vec3 m = n;
    for (int e = fc.x; e < fc.x + fc.y; ++e) {
        vec4 dp = texelFetch(u_targets_delta, targets_texel(2 * e), 0);
        int c = int(dp.w);
        float w = mix(texelFetch(u_targets_weight, ivec2(c, f0), 0).x,
                      texelFetch(u_targets_weight, ivec2(c, f1), 0).x, a);
        if (w == 0.0) continue;
        p += w * dp.xyz;
        m += w * texelFetch(u_targets_delta, targets_texel(2 * e + 1), 0).xyz;
    }
    float lm = dot(m, m);
    if (lm > 1e-30) n = m * inversesqrt(lm);
}
#endif
