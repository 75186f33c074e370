// Geomorph targets (lod/clusters/morph.py, lod/chains/mode.py): a vertex of a
// fine representation blends towards the vertex it has collapsed into in a
// coarser one (a cluster's ancestor, a later level of a LOD chain), found by
// following its collapse chain. Two textures, MORPH_WIDTH texels wide
// (render/clusters/morph.py morph_textures):
//   u_morph_i (RGBA32I), 2 texels per vertex: (next vertex, height / level of
//       the cluster or level that removes it, 0, 0), joints;
//   u_morph_f (RGBA32F), 4 texels per vertex: position, normal, colour, weights.
// Include after skinning.glsl (the target is skinned like the vertex) and,
// in the MORPH_TARGETS variants, after instance.glsl and targets.glsl.
uniform isampler2D u_morph_i;
uniform sampler2D u_morph_f;

// Chains climb strictly in height, so this bounds them (lod.clusters.morph.MAX_CHAIN);
// it only guards a corrupt table.
const int MAX_CHAIN = 64;
// texture width 4096 = 2^12: texel t sits at (t & 4095, t >> 12)
ivec2 texel(int t) { return ivec2(t & 4095, t >> 12); }

// The vertex v has become at height (cluster) or level (chain) h: follow the
// chain while the step that removes the current vertex is no higher than h.
int morph_target(int v, int h) {
    int x = v;
    for (int s = 0; s < MAX_CHAIN; ++s) {
        ivec4 m = texelFetch(u_morph_i, texel(2 * x), 0);
        if (m.y > h) break;
        x = m.x;
    }
    return x;
}

// The bind-pose attributes and skin of vertex x.
void morph_attributes(int x, out vec3 pos, out vec3 nrm, out vec4 col, out uvec4 joints, out vec4 weights) {
    pos = texelFetch(u_morph_f, texel(4 * x), 0).xyz;
    nrm = texelFetch(u_morph_f, texel(4 * x + 1), 0).xyz;
    col = texelFetch(u_morph_f, texel(4 * x + 2), 0);
    weights = texelFetch(u_morph_f, texel(4 * x + 3), 0);
    joints = uvec4(texelFetch(u_morph_i, texel(2 * x + 1), 0));
}

// Blend the skinned position p, normal n and colour of vertex v by w towards
// the vertex it has become at height / level h, skinned like v: from the
// palette block ``slot`` (``palette``: the palette path) or from the baked
// frames around ``frame`` (the direct path).
void morph_blend(int v, int h, float w, bool palette, int slot, float frame,
                 inout vec3 p, inout vec3 n, inout vec4 color) {
    if (h < 0 || !(w > 0.0)) return;
    int x = morph_target(v, h);
    if (x == v) return;
    vec3 tp, tn;
    vec4 tc, tw;
    uvec4 tj;
    morph_attributes(x, tp, tn, tc, tj, tw);
#ifdef MORPH_TARGETS
    targets_apply(x, i_anim.x, tp, tn);  // the target vertex is morphed like v (targets.glsl)
#endif
    vec4 q0, q1, q2;
    if (palette) palette_rows(tj, tw, slot, q0, q1, q2);
    else skin_rows(tj, tw, frame, q0, q1, q2);
    vec4 th = vec4(tp, 1.0);
    p = mix(p, vec3(dot(q0, th), dot(q1, th), dot(q2, th)), w);
    n = mix(n, skin_normal(q0, q1, q2, tn), w);
    color = mix(color, tc, w);
}
