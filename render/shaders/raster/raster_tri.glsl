#version 430
// Triangle passes of the compute rasteriser (render/raster/frame.py), after the vertex pass wrote every
// vertex's fixed-point window position (raster_vertex.glsl).
//
// Default (depth pass): one work group of 8 threads per job (an instance and up to RS_CHUNK of its
// triangles), a thread per triangle. A triangle all of whose vertices lie outside one clip plane is culled;
// one with a vertex behind the near plane, or whose window bounding box is wider or taller than u_max_extent
// (fixed point), goes to the hardware path (the spill lists: culling characters, other characters, the world);
// a back face of a culling instance and a degenerate triangle are culled; the others are rasterised: every
// pixel centre of the bounding box inside the screen is tested with the three edge functions in integer
// arithmetic (exact) with the fill rule llvmpipe applies to GL (a sample on an edge belongs to the triangle
// when the edge is a bottom or a left one in window coordinates, y up: the top-left rule of the y-down
// image), depth interpolated from the exact edge values, and atomicMin of the depth key (float bits of the
// window depth in [0, 1], ordered as uint) into Depth. A triangle whose atomic lowered (or tied) a pixel's key
// is appended to the candidate list; the others can own no pixel.
// ID_PASS: a thread per candidate; where the final key equals the triangle's depth, atomicMin of the
// triangle's id (job * RS_CHUNK + index) into Ids: of triangles tied in depth the lowest id wins, whatever
// order the threads ran in. (64-bit atomics would make it one pass; llvmpipe offers none.)
layout(local_size_x = 8) in;
#include "raster_common.glsl"

uniform isampler2D u_screen;
layout(std430, binding = 0) buffer Depth { uint depth[]; };
layout(std430, binding = 1) buffer Ids { uint ids[]; };
// [0] candidates, [1..3] set-aside triangles of culling characters, other characters, the world
layout(std430, binding = 2) buffer Counts { uint counts[]; };
layout(std430, binding = 3) buffer Candidates { uint cand[]; };
layout(std430, binding = 4) buffer Spill { uint spill[]; };
uniform ivec2 u_size;
uniform uint u_count;      // jobs (depth pass) or candidates (id pass)
uniform int u_max_extent;  // most fixed-point units a rasterised triangle's box spans (threshold x 256)
uniform uint u_spill_cap;  // entries of each list in Spill (three lists one after another)
#ifdef ID_PASS
// one flag per RS_TILE x RS_TILE pixels: the tiles holding a won pixel, which the shading pass draws
layout(std430, binding = 6) buffer Tiles { uint tiles[]; };
uniform int u_tiles_x;
#endif
#ifndef RS_TILE
#define RS_TILE 8
#endif

ivec4 screen_of(uint s) { return texelFetch(u_screen, rs_texel(s), 0); }

// edge function of edge a -> b at p (relative fixed-point coordinates): >= 0 left of the edge
int edge(ivec2 a, ivec2 b, ivec2 p) { return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x); }

// 0 where a sample exactly on edge a -> b of a counter-clockwise triangle belongs to it (a bottom edge:
// dy == 0, dx > 0; a left edge: dy < 0), else -1 (the sample must be strictly inside)
int edge_bias(ivec2 a, ivec2 b) {
    ivec2 d = b - a;
    return (d.y < 0 || (d.y == 0 && d.x > 0)) ? 0 : -1;
}

void rasterise(uint item, uint flags, ivec4 a, ivec4 b, ivec4 c) {
    // relative to vertex a: differences of clamped window coordinates fit, products below 2^31 within the
    // extent limit (render/raster/frame.py MAX_THRESHOLD)
    ivec2 f0 = ivec2(0);
    ivec2 f1 = b.xy - a.xy;
    ivec2 f2 = c.xy - a.xy;
    float z0 = intBitsToFloat(a.z);
    float z1 = intBitsToFloat(b.z);
    float z2 = intBitsToFloat(c.z);
    int area = edge(f0, f1, f2);
    if (area == 0) return;
    if (area < 0) {
        if ((flags & RS_CULL) != 0u) return;  // back face (counter-clockwise is front, as GL's default)
        ivec2 t = f1; f1 = f2; f2 = t;
        float tz = z1; z1 = z2; z2 = tz;
        area = -area;
    }
    ivec2 lo = (min(min(a.xy, b.xy), c.xy) + 255) >> 8;  // first pixel centre at or right/above the box
    ivec2 hi = max(max(a.xy, b.xy), c.xy) >> 8;
    lo = max(lo, ivec2(0));
    hi = min(hi, u_size - 1);
    int bias0 = edge_bias(f1, f2);
    int bias1 = edge_bias(f2, f0);
    int bias2 = edge_bias(f0, f1);
    float inv = 1.0 / float(area);
    float d1 = z1 - z0;
    float d2 = z2 - z0;
    bool wrote = false;
    // edge values at the first pixel centre of the box, stepped exactly in integers: +256 * (-dy) per pixel
    // along x and +256 * dx per row (raster_reference.py evaluates each pixel afresh: the same integers)
    ivec2 p0 = (lo << 8) - a.xy;
    ivec3 row = ivec3(edge(f1, f2, p0), edge(f2, f0, p0), edge(f0, f1, p0));
    ivec3 sx = ivec3(f1.y - f2.y, f2.y - f0.y, f0.y - f1.y) << 8;
    ivec3 sy = ivec3(f2.x - f1.x, f0.x - f2.x, f1.x - f0.x) << 8;
    ivec3 bias = ivec3(bias0, bias1, bias2);
    for (int y = lo.y; y <= hi.y; ++y) {
        ivec3 w = row;
        row += sy;
        for (int x = lo.x; x <= hi.x; ++x, w += sx) {
            ivec3 wb = w + bias;
            if ((wb.x | wb.y | wb.z) < 0) continue;
            float z = z0 + (float(w.y) * d1 + float(w.z) * d2) * inv;
            if (!(z >= 0.0 && z <= 1.0)) continue;  // beyond the far plane (near: the hardware path)
            uint key = floatBitsToUint(z);
            uint at = uint(y * u_size.x + x);
#if defined(COUNT_PASS)
            atomicAdd(ids[at], 1u);  // diagnostic: how many triangles cover each pixel (Raster.hit_counts)
#elif defined(ID_PASS)
            if (depth[at] == key) {
                atomicMin(ids[at], item);
                tiles[(y / RS_TILE) * u_tiles_x + x / RS_TILE] = 1u;  // every writer stores the same value
            }
#else
            if (atomicMin(depth[at], key) >= key) wrote = true;
#endif
        }
    }
#if !defined(ID_PASS) && !defined(COUNT_PASS)
    if (wrote) cand[atomicAdd(counts[0], 1u)] = item;
#endif
}

// triangle ``item`` of job ``job`` whose instance's first screen vertex is ``screen``
void triangle(uint item, uvec4 job, uint screen, uint flags) {
    uvec3 t = rs_triangle(job.x + (item & (RS_CHUNK - 1u)));
    ivec4 a = screen_of(screen + t.x);
    ivec4 b = screen_of(screen + t.y);
    ivec4 c = screen_of(screen + t.z);
    if ((a.w & b.w & c.w & 63) != 0) return;  // outside one clip plane: culled
#ifndef ID_PASS
    bool aside = ((a.w | b.w | c.w) & 16) != 0;  // crosses the near plane: clipped by the hardware
    if (!aside) {
        ivec2 lo = min(min(a.xy, b.xy), c.xy);
        ivec2 hi = max(max(a.xy, b.xy), c.xy);
        if (hi.x < -128 || hi.y < -128 || lo.x > (u_size.x << 8) - 128 || lo.y > (u_size.y << 8) - 128) return;
        aside = hi.x - lo.x > u_max_extent || hi.y - lo.y > u_max_extent;
    }
    if (aside) {
        uint list = (flags & RS_WORLD) != 0u ? 3u : ((flags & RS_CULL) != 0u ? 1u : 2u);
        uint s = atomicAdd(counts[list], 1u);
        if (s < u_spill_cap) spill[(list - 1u) * u_spill_cap + s] = item;
        return;
    }
#endif
    rasterise(item, flags, a, b, c);
}

// the first screen vertex and the flags of instance i (raster_common.glsl RsInstance)
uvec2 screen_flags(uint i) {
    uint t = i * RS_INST;
    return uvec2(texelFetch(u_rs_inst, rs_texel(t + 4u), 0).x, texelFetch(u_rs_inst, rs_texel(t + 3u), 0).y >> 8);
}

void main() {
    uint g = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
#ifdef ID_PASS
    uint c = g * 8u + gl_LocalInvocationID.x;
    if (c >= u_count) return;
    uint item = cand[c];
    uvec4 job = rs_job(item >> RS_LOG_CHUNK);
    uvec2 sf = screen_flags(job.z);
    triangle(item, job, sf.x, sf.y);
#else
    if (g >= u_count) return;
    uvec4 job = rs_job(g);  // once per thread: its instance's screen vertices and flags
    uvec2 sf = screen_flags(job.z);
    for (uint k = gl_LocalInvocationID.x; k < job.y; k += 8u) triangle((g << RS_LOG_CHUNK) + k, job, sf.x, sf.y);
#endif
}
