#version 430
// Resets the anchor slots of the point splat (depth, and colour: NEAREST one packed colour, else four
// accumulators set to 0) to "empty" and
// their touched-tile flags (render/points/draw.py TILE) to 0. Default: every slot and
// flag, one thread each. TILE_LIST: only the u_count slot tiles listed in
// Dirty (those the last frame filled), one work group of TILE x TILE threads
// per TILES_PER_GROUP tiles.
#ifndef TILE
#define TILE 8
#endif
#ifndef TILES_PER_GROUP
#define TILES_PER_GROUP 1
#endif
#ifdef TILE_LIST
layout(local_size_x = TILE, local_size_y = TILE) in;
#else
layout(local_size_x = 256) in;
#endif
layout(std430, binding = 3) buffer Depth { uint depth[]; };
layout(std430, binding = 4) buffer Color { uint color[]; };
layout(std430, binding = 8) buffer Tiles { uint tiles[]; };
layout(std430, binding = 10) readonly buffer Dirty { uint dirty[]; };
uniform uint u_pixels;
uniform uint u_ntiles;
uniform uint u_count;
uniform ivec2 u_slots;  // anchor slot grid: (width + MARGIN, height + MARGIN)
uniform int u_tiles_x;

void clear_color(uint slot) {
#ifdef NEAREST
    color[slot] = 0xFFFFFFFFu;
#else
    color[4u * slot] = 0u;
    color[4u * slot + 1u] = 0u;
    color[4u * slot + 2u] = 0u;
    color[4u * slot + 3u] = 0u;
#endif
}

void main() {
#ifdef TILE_LIST
    uint g = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    for (uint q = 0u; q < uint(TILES_PER_GROUP); ++q) {
        uint e = g * uint(TILES_PER_GROUP) + q;
        if (e >= u_count) return;
        uint t = dirty[e];
        ivec2 s = ivec2(int(t) % u_tiles_x, int(t) / u_tiles_x) * TILE + ivec2(gl_LocalInvocationID.xy);
        if (s.x < u_slots.x && s.y < u_slots.y) {
            depth[s.y * u_slots.x + s.x] = 0xFFFFFFFFu;
            clear_color(uint(s.y * u_slots.x + s.x));
        }
        if (gl_LocalInvocationIndex == 0u) tiles[t] = 0u;
    }
#else
    uint g = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 256u;
    if (g < u_pixels) {
        depth[g] = 0xFFFFFFFFu;
        clear_color(g);
    }
    if (g < u_ntiles) tiles[g] = 0u;
#endif
}
