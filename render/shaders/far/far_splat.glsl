#version 430
// The far tier's splat (render/far/draw.py; issue 45): one thread per far agent. The agent's bounding-sphere
// centre is projected to its pixel; its footprint table (lod/far/footprint.py, sliced at the frame's light
// elevation by the drawer) gives, bilinearly in the view direction (azimuth relative to its heading,
// elevation) and linearly in the light's azimuth relative to its heading, the covered area (m^2 at scale 1)
// and the mean lit colour of what it shows. Its coverage of the pixel is alpha = min(1, area in pixels);
// the pixel's accumulators add colour x alpha, alpha, -log(1 - alpha) (integers: order-free) and keep the
// nearest depth (atomicMin of the window depth's bits: positive floats order as their bits). The visible part
// of the agent's blob shadow (m^2 of full opacity seen from above, the alpha of the cell's first direct vec4;
// 0 without blob shadows) foreshortened by the view's elevation and in pixels adds -log(1 - shadow).
// Compiled variants (render/far/draw.py): BLOBS when the renderer draws blob shadows, VARIED when the batch's
// agents carry colour-variation words (the code of either costs llvmpipe ~15 ms a million agents, taken or not).
layout(local_size_x = 64) in;

#include "tint.glsl"

#define VA 16
#define VE 9
#define LA 16
#define VARIED_VEC4 (LA / 4)
#define CELL (1 + LA + 1 + VARIED_VEC4)
#define CLIP_VEC4 (1 + VE * VA * CELL)
#define SCALE 4096.0
#define MAX_ALPHA 0.999

layout(std430, binding = 0) readonly buffer Rows { vec4 rows[]; };    // camera-relative xyz, scale
layout(std430, binding = 1) readonly buffer Words { uint words[]; };  // heading (1/65536 turns) | clip << 16
layout(std430, binding = 2) readonly buffer Table { vec4 table[]; };
#ifdef VARIED
layout(std430, binding = 4) readonly buffer Tints { uint tints[]; };  // the agents' variation words (lod/variation.py)
#endif
layout(std430, binding = 3) buffer Accum { uint acc[]; };  // per pixel: depth, r, g, b, alpha, -log(1-a), -log(1-s)

uniform mat4 u_view_proj;
uniform ivec2 u_size;
uniform uint u_count;
uniform uint u_base;        // first vec4 of this representation's tables
uniform float u_light_az;   // azimuth of the light (world, radians, atan(x, z))
uniform vec2 u_pixels;      // (P00 w / 2, P11 h / 2): pixels per metre at clip w = 1
uniform vec3 u_light_color;
uniform vec4 u_tint;        // the batch's debug colour (rgb, weight; lod/debug_colors.py), mixed into the splat's

const float TAU = 6.283185307179586;

vec4 lookup(uint cb, int e, int a, int l0, int l1, float tl) {
    uint cell = cb + 1u + uint(e * VA + a) * uint(CELL);
    vec4 t0 = table[cell];
    vec3 d = mix(table[cell + 1u + uint(l0)].rgb, table[cell + 1u + uint(l1)].rgb, tl);
    return vec4(t0.rgb + d, t0.a);
}

// the change an agent's variation word makes to a cell's mean lit colour: the varied part's mean base colour
// varied by the word, less itself, times that part's lighting (ambient and headlight, and the direct term at
// the light's azimuth)
#ifdef VARIED
// the varied part of a view cell: (its mean base colour, its ambient and headlight terms), and its direct term
// at the light's azimuth (mixed between the two grid azimuths around it)
vec4 varied_base(uint cb, int e, int a) {
    return table[cb + 1u + uint(e * VA + a) * uint(CELL) + 1u + uint(LA)];
}

float varied_direct(uint cb, int e, int a, int l0, int l1, float tl) {
    uint cell = cb + 1u + uint(e * VA + a) * uint(CELL) + 2u + uint(LA);
    return mix(table[cell + uint(l0 / 4)][l0 % 4], table[cell + uint(l1 / 4)][l1 % 4], tl);
}
#endif

float ground(uint cb, int e, int a) {
    return table[cb + 1u + uint(e * VA + a) * uint(CELL) + 1u].a;
}

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    if (i >= u_count) return;
    vec4 row = rows[i];
    uint word = words[i];
    float h = float(word & 0xFFFFu) * (TAU / 65536.0);
    uint cb = u_base + (word >> 16) * uint(CLIP_VEC4);
    float s = row.w;
    vec3 c = table[cb].xyz;
    float ch = cos(h), sh = sin(h);
    vec3 p = row.xyz + vec3(ch * c.x + sh * c.z, c.y, -sh * c.x + ch * c.z) * s;
    vec4 clip = u_view_proj * vec4(p, 1.0);
    if (!(clip.w > 0.0)) return;
    vec3 ndc = clip.xyz / clip.w;
    if (any(greaterThan(abs(ndc), vec3(1.0)))) return;
    ivec2 px = ivec2(floor((ndc.xy * 0.5 + 0.5) * vec2(u_size)));
    if (any(lessThan(px, ivec2(0))) || any(greaterThanEqual(px, u_size))) return;
    // the view direction (agent -> camera) and the light in the agent's frame: azimuths less its heading
    vec3 v = -p;
    float lv = length(v);
    v = lv > 0.0 ? v / lv : vec3(0.0, 1.0, 0.0);
    float el = degrees(asin(clamp(v.y, -1.0, 1.0)));
    float fe = clamp((el + 90.0) / 180.0 * float(VE - 1), 0.0, float(VE - 1));
    int e0 = min(int(floor(fe)), VE - 2);
    float te = fe - float(e0);
    float az = atan(v.x, v.z) - h;
    float fa = fract(az / TAU) * float(VA);
    int a0 = int(floor(fa)) % VA;
    float ta = fa - floor(fa);
    int a1 = (a0 + 1) % VA;
    float fl = fract((u_light_az - h) / TAU) * float(LA);
    int l0 = int(floor(fl)) % LA;
    float tl = fl - floor(fl);
    int l1 = (l0 + 1) % LA;
    vec4 r = mix(mix(lookup(cb, e0, a0, l0, l1, tl), lookup(cb, e0, a1, l0, l1, tl), ta),
                 mix(lookup(cb, e0 + 1, a0, l0, l1, tl), lookup(cb, e0 + 1, a1, l0, l1, tl), ta), te);
#ifdef VARIED
    // the change the agent's variation word makes: the varied part's mean base colour of the nearest view cell
    // varied by the word, less itself, lit with that part's own terms (one variation, three loads per agent: the
    // correction is a share of the colour, the cell's neighbours differ from it by little)
    uint vw = tints[i];
    if ((vw >> 24) != 0u) {
        int en = min(int(fe + 0.5), VE - 1);
        int an = (a0 + int(ta + 0.5)) % VA;
        vec4 vb = varied_base(cb, en, an);
        float vd = varied_direct(cb, en, an, l0, l1, tl);
        vec3 changed = tint_color(vec4(vb.rgb, 1.0), uvec2(vw, 0u)).rgb - clamp(vb.rgb, 0.0, 1.0);
        r.rgb += changed * (vec3(vb.a) + u_light_color * vd);
    }
#endif
    float px_m2 = s * s * u_pixels.x * u_pixels.y / (clip.w * clip.w);  // pixels per m^2 of the agent
    float alpha = min(r.a * px_m2, 1.0);
    uint wa = uint(alpha * SCALE + 0.5);
#ifdef BLOBS
    // the visible blob of the nearest view cell (a share of the pixel's darkening; one load)
    float g = ground(cb, min(int(fe + 0.5), VE - 1), (a0 + int(ta + 0.5)) % VA);
    float shade = min(g * abs(v.y) * px_m2, MAX_ALPHA);
    uint ws = uint(-log(1.0 - shade) * SCALE + 0.5);
#else
    uint ws = 0u;
#endif
    if (wa == 0u && ws == 0u) return;  // nothing visible: no depth either (the resolve resets what it reads)
    uint k = uint(px.y * u_size.x + px.x) * 7u;
    atomicMin(acc[k], floatBitsToUint(ndc.z * 0.5 + 0.5));
    vec3 col = mix(clamp(r.rgb, 0.0, 16.0), u_tint.rgb, u_tint.a) * float(wa);
    atomicAdd(acc[k + 1u], uint(col.r + 0.5));
    atomicAdd(acc[k + 2u], uint(col.g + 0.5));
    atomicAdd(acc[k + 3u], uint(col.b + 0.5));
    atomicAdd(acc[k + 4u], wa);
    atomicAdd(acc[k + 5u], uint(-log(1.0 - min(alpha, MAX_ALPHA)) * SCALE + 0.5));
    if (ws != 0u) atomicAdd(acc[k + 6u], ws);
}
