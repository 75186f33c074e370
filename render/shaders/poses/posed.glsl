// The pose cache's posed vertices (render/poses/cache.py): every distinct pose
// of a character skinned once per frame, model space, morph targets applied,
// laid out [slot][vertex] in one RGBA32F texture per window, POSED_WIDTH = 4096
// texels per row, two texels per vertex: (p.xyz, n.x), (n.y, n.z, 0, 0), n a unit
// normal -- the compute rasteriser's posed-table layout (raster_common.glsl
// RS_POSED), so it reads a window in place. Vertex v of slot s is texel
// t = 2 ((s - u_posed_first) * u_posed_vertices + v) at (t & 4095, t >> 12).
// (Textures, not storage buffers: llvmpipe scalarises and bounds-checks
// per-lane storage-buffer loads; texelFetch is several times cheaper.) A
// frame's slots are cut into windows of whole slots, one texture each, no
// larger than the texture limits and the cache's window size; u_posed_first is
// the first slot of the bound window.
// Readers (the draw of copies, posed.vert; compute passes) sample u_posed; the
// skinning pass (pose_skin.comp, POSED_WRITE) stores through image unit 0.
uniform int u_posed_vertices;  // vertices per pose
uniform int u_posed_first;     // first slot of the bound window

int posed_index(int slot, int v) { return 2 * ((slot - u_posed_first) * u_posed_vertices + v); }
ivec2 posed_at(int t) { return ivec2(t & 4095, t >> 12); }

#ifdef POSED_WRITE
layout(rgba32f, binding = 0) writeonly uniform image2D u_posed_out;

void posed_store(int slot, int v, vec3 p, vec3 n) {
    int t = posed_index(slot, v);
    imageStore(u_posed_out, posed_at(t), vec4(p, n.x));
    imageStore(u_posed_out, posed_at(t + 1), vec4(n.yz, 0.0, 0.0));
}
#else
uniform sampler2D u_posed;

// position and normal of vertex v of slot (two texels)
void posed_vertex(int slot, int v, out vec3 p, out vec3 n) {
    int t = posed_index(slot, v);
    vec4 a = texelFetch(u_posed, posed_at(t), 0);
    vec4 b = texelFetch(u_posed, posed_at(t + 1), 0);
    p = a.xyz;
    n = vec3(a.w, b.xy);
}
#endif
