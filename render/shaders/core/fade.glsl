// Screen-door transition of DrawBatch.fade (lod/drawlist.py): u_fade.x = t in
// [0, 1], u_fade.y = +1 for the outgoing batch (kept where dither >= t), -1 for
// the incoming one (kept where dither < t), 0 = no fade. The 8x8 Bayer matrix
// gives 64 thresholds spread evenly over every 8x8 block, so the covered
// fraction of either batch changes by 1/64 steps uniformly in space, and the
// two patterns are exact complements (Friedrich, Polthier, Schmies §3, blend
// between keyframe selections, done as a per-pixel choice).
uniform vec2 u_fade;

float fade_threshold(ivec2 p) {
    uint x = uint(p.x) & 7u;
    uint y = uint(p.y) & 7u;
    uint z = x ^ y;
    uint b = ((z & 1u) << 5) | ((y & 1u) << 4) | ((z & 2u) << 2) | ((y & 2u) << 1) | ((z & 4u) >> 1) | ((y & 4u) >> 2);
    return (float(b) + 0.5) / 64.0;
}

bool fade_discards(ivec2 p) {
    if (u_fade.y == 0.0) return false;
    float h = fade_threshold(p);
    return u_fade.y > 0.0 ? (h < u_fade.x) : (h >= u_fade.x);
}
