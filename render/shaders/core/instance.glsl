// Per-instance data (instanced attributes, divisor 1): rows 0..2 of the
// camera-relative model matrix and four animation floats (lod/drawlist.py),
// and the instance's colour words (variation, debug; render/tint.py), read by
// tint_color (tint.glsl; unbound they are 0: true colours).
in vec4 i_m0;
in vec4 i_m1;
in vec4 i_m2;
in vec4 i_anim;
in uvec2 i_tint;
#include "tint.glsl"

vec3 instance_point(vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(i_m0, h), dot(i_m1, h), dot(i_m2, h));
}

vec3 instance_dir(vec3 d) {
    return vec3(dot(i_m0.xyz, d), dot(i_m1.xyz, d), dot(i_m2.xyz, d));
}

// The palette block of this copy (skinning.glsl palette_rows): its pose slot
// (i_anim.y) when the pose cache blended one palette per distinct pose
// (POSE_SLOT variants, render/poses/cache.py), else its instance (one block per
// copy, built by the per-frame pre-pass).
int palette_index() {
#ifdef POSE_SLOT
    return int(i_anim.y + 0.5);
#else
    return gl_InstanceID;
#endif
}
