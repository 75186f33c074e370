#version 430
// Compute-shader point splatting (Schuetz, Kerbl, Wimmer, "Rendering Point
// Clouds with Compute Shaders"), two passes over the frame's selected points.
// One work group per JOBS_PER_GROUP consecutive jobs (a job: an instance and a range of its segment's points):
// its LOCAL_SIZE threads stride over the range (8, llvmpipe's SIMD width,
// measured 2x faster than 64 there; render/points/draw.py SPLAT_GROUP), so no search is needed to find the
// instance, and the instance's matrix and u are read once per thread.
// DEPTH_PASS (default): atomicMin of the window depth (float bits, positive,
// so ordered as uint) into the point's anchor slot (the lowest corner of its
// s x s footprint, on a grid with a MARGIN-pixel border below and left); the
// first point of an anchor marks the anchor's TILE x TILE tile
// (render/points/draw.py clears and resolves only marked tiles).
// COLOR_PASS: every point within the depth tolerance of its anchor's nearest
// (eye depth w <= w_min (1 + u_tol): the nearest surface, Schuetz, Kerbl and
// Wimmer 2021's high-quality splatting) loads its normal and colour and adds
// its lit colour times its weight, and the weight, into the anchor's four
// accumulators (integer atomicAdd: the sums do not depend on the order the
// threads run in). The weight is the point's projected area, |n . v| (a
// splat seen edge-on covers little of the surface it stands for), quantised
// to 1..16 (FLAT_WEIGHT: 16 for every point). NEAREST: the winner alone writes its colour (atomicMin of the
// packed colour: of points tied in depth the smallest), the old rule. The
// resolve pass takes, per pixel, the nearest of the s x s anchors whose
// footprints cover it and the anchors within the tolerance of it: the same
// as scattering into the whole footprint, with one atomic per point (four
// when blending) instead of s * s.
// (llvmpipe has no 64-bit atomics, so depth and index cannot be packed into
// one 64-bit atomicMin.)
#ifndef MARGIN
#define MARGIN 2
#endif
#ifndef TILE
#define TILE 8
#endif
#ifndef LOCAL_SIZE
#define LOCAL_SIZE 8
#endif
layout(local_size_x = LOCAL_SIZE) in;
#include "points_common.glsl"
#include "fade.glsl"

#ifdef PLACED
// samples placed with the animation this frame (render/points/follow.py, points_placed.glsl)
layout(std430, binding = 0) readonly buffer Placed { uvec4 placed[]; };
#else
layout(std430, binding = 0) readonly buffer Points { Sample pts[]; };
#endif
layout(std430, binding = 3) buffer Depth { uint depth[]; };
// per anchor: NEAREST one packed colour; else (sum r w, sum g w, sum b w, sum w), colours in 0..255
layout(std430, binding = 4) buffer Color { uint color[]; };
#ifndef COLOR_PASS
// filled-tile flags, one per TILE x TILE anchor slots
layout(std430, binding = 8) buffer Tiles { uint tiles[]; };
#endif

uniform mat4 u_view_proj;
uniform ivec2 u_size;
uniform int u_splat;
uniform int u_tiles_x;  // slot tiles per row: ceil((width + MARGIN) / TILE)
#if defined(COLOR_PASS) && !defined(NEAREST)
uniform vec2 u_depth_ab;  // eye depth of window depth d: w = u_depth_ab.y / (u_depth_ab.x - (2 d - 1))
uniform float u_tol;      // relative eye-depth tolerance of the blend
#endif

#ifndef JOBS_PER_GROUP
#define JOBS_PER_GROUP 1
#endif

void splat_job(uint j, uint k0, uint stride);

#if defined(COLOR_PASS) && !defined(NEAREST)
float eye_depth(float d) {
    return u_depth_ab.y / (u_depth_ab.x - (2.0 * d - 1.0));
}

// the blend weight of a point: its projected area |n . v| (n and the view ray normalised; a zero normal
// counts as facing the camera), quantised to 1..16 so that a point seen edge-on still counts a little
uint splat_weight(vec3 world, vec3 nw) {
#ifdef FLAT_WEIGHT
    return 16u;
#endif
    float ln = dot(nw, nw);
    float lv = dot(world, world);
    float f = (ln > 1e-20 && lv > 1e-20) ? abs(dot(nw, world)) * inversesqrt(ln * lv) : 1.0;
    return 1u + uint(round(15.0 * clamp(f, 0.0, 1.0)));
}
#endif

void main() {
    uint g = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    // JOBS_PER_GROUP consecutive jobs per work group: far views have many
    // short jobs, and each work group has a fixed cost on llvmpipe
    for (uint q = 0u; q < uint(JOBS_PER_GROUP); ++q) {
#ifdef THREAD_PER_JOB
        // short jobs (a few points: far agents drawn coarser than their root, lod/points/coarse.py):
        // one job per thread, JOBS_PER_GROUP x LOCAL_SIZE consecutive jobs per work group
        uint j = (g * uint(JOBS_PER_GROUP) + q) * uint(LOCAL_SIZE) + gl_LocalInvocationID.x;
        if (j >= u_njobs) return;
        splat_job(j, 0u, 1u);
#else
        uint j = g * uint(JOBS_PER_GROUP) + q;
        if (j >= u_njobs) return;
        splat_job(j, gl_LocalInvocationID.x, uint(LOCAL_SIZE));
#endif
    }
}

void splat_job(uint j, uint k0, uint stride) {
    uvec4 job = jobs[j];
    uint i = job.z;
    float u = inst_u(i);
    vec4 m0 = inst[4u * i];
    vec4 m1 = inst[4u * i + 1u];
    vec4 m2 = inst[4u * i + 2u];
    // model-view-projection of this instance, once per thread
    mat4 model = transpose(mat4(m0, m1, m2, vec4(0.0, 0.0, 0.0, 1.0)));
    mat4 mvp = u_view_proj * model;
    float half_s = 0.5 * float(u_splat);
    for (uint k = k0; k < job.y; k += stride) {
        // positions only: the colour pass loads a point's normal and colour
        // once it has won its anchor (most points of a far view lose)
#ifdef PLACED
        vec3 p = placed_pos(placed[job.x + k]);
#else
        vec3 p = sample_pos(pts[job.x + k].geo, u);
#endif
        vec4 clip = mvp * vec4(p, 1.0);
        if (!(clip.w > 0.0)) continue;
        vec3 ndc = clip.xyz / clip.w;
        if (ndc.z < -1.0 || ndc.z > 1.0) continue;
        float x = (ndc.x * 0.5 + 0.5) * float(u_size.x);
        float y = (ndc.y * 0.5 + 0.5) * float(u_size.y);
        // the footprint is the s x s pixels from the anchor (x0, y0): those
        // whose centres lie in [x - s/2, x + s/2) (the GL point rule)
        int x0 = int(ceil(x - half_s - 0.5));
        int y0 = int(ceil(y - half_s - 0.5));
        if (x0 < -MARGIN || y0 < -MARGIN || x0 >= u_size.x || y0 >= u_size.y) continue;
        // screen-door transition (DrawBatch.fade): decided at the anchor, the same in both passes
        if (fade_discards(ivec2(x0, y0))) continue;
        int sx = x0 + MARGIN;
        int sy = y0 + MARGIN;
        uint slot = uint(sy * (u_size.x + MARGIN) + sx);
        uint key = floatBitsToUint(ndc.z * 0.5 + 0.5);
#ifdef COLOR_PASS
#ifdef NEAREST
        bool take = depth[slot] == key;
#else
        uint near_key = depth[slot];
        bool take = near_key == key || (near_key != 0xFFFFFFFFu
            && clip.w <= eye_depth(uintBitsToFloat(near_key)) * (1.0 + u_tol));
#endif
        if (take) {
            vec3 n;
            vec4 c;
#ifdef PLACED
            placed_at(placed[job.x + k], p, n, c);
#else
            sample_at(pts[job.x + k], u, p, n, c);
#endif
            vec4 h = vec4(p, 1.0);
            vec3 world = vec3(dot(m0, h), dot(m1, h), dot(m2, h));
            vec3 nw = vec3(dot(m0.xyz, n), dot(m1.xyz, n), dot(m2.xyz, n));
            vec3 lit = shade(world, nw, tint_color(c, tints[i]).rgb);
#ifdef NEAREST
            // points at the same depth (a tie) all pass the test above: the
            // smallest packed colour wins, so the image does not depend on the
            // order the threads run in (a plain store did)
            atomicMin(color[slot], packUnorm4x8(vec4(lit, 1.0)));
#else
            uint q = splat_weight(world, nw);
            uvec3 c8 = uvec3(round(clamp(lit, 0.0, 1.0) * 255.0)) * q;
            atomicAdd(color[4u * slot], c8.r);
            atomicAdd(color[4u * slot + 1u], c8.g);
            atomicAdd(color[4u * slot + 2u], c8.b);
            atomicAdd(color[4u * slot + 3u], q);
#endif
        }
#else
        // the first point of an anchor marks its tile (every writer stores the
        // same value: no atomic needed)
        if (atomicMin(depth[slot], key) == 0xFFFFFFFFu) tiles[(sy / TILE) * u_tiles_x + sx / TILE] = 1u;
#endif
    }
}
