// The pose cache's posed vertices (render/poses/cache.py): every distinct pose
// of a character skinned once per frame, model space, morph targets applied,
// laid out [slot][vertex] in two RGBA32F textures of POSED_WIDTH = 4096 texels
// per row: positions (x, y, z, 1) and unit normals (nx, ny, nz, 0); linear
// texel t = (slot - u_posed_first) * u_posed_vertices + vertex sits at
// (t & 4095, t >> 12). (Textures, not storage buffers: llvmpipe scalarises and
// bounds-checks per-lane storage-buffer loads; texelFetch is several times
// cheaper.) A frame's slots are cut into windows of whole slots, one texture
// pair each, no larger than the texture limits and the cache's window size;
// u_posed_first is the first slot of the bound window.
// Readers (the draw of copies, posed.vert; compute passes) sample
// u_posed_positions / u_posed_normals; the skinning pass (pose_skin.comp,
// POSED_WRITE) stores through the image units 0 and 1.
uniform int u_posed_vertices;  // vertices per pose
uniform int u_posed_first;     // first slot of the bound window

ivec2 posed_texel(int slot, int v) {
    int t = (slot - u_posed_first) * u_posed_vertices + v;
    return ivec2(t & 4095, t >> 12);
}

#ifdef POSED_WRITE
layout(rgba32f, binding = 0) writeonly uniform image2D u_posed_positions_out;
layout(rgba32f, binding = 1) writeonly uniform image2D u_posed_normals_out;

void posed_store(int slot, int v, vec3 p, vec3 n) {
    ivec2 at = posed_texel(slot, v);
    imageStore(u_posed_positions_out, at, vec4(p, 1.0));
    imageStore(u_posed_normals_out, at, vec4(n, 0.0));
}
#else
uniform sampler2D u_posed_positions;
uniform sampler2D u_posed_normals;

vec3 posed_position(int slot, int v) { return texelFetch(u_posed_positions, posed_texel(slot, v), 0).xyz; }
vec3 posed_normal(int slot, int v) { return texelFetch(u_posed_normals, posed_texel(slot, v), 0).xyz; }
#endif
