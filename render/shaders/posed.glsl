// The pose cache's posed vertices (render/pose_cache.py): every distinct pose
// of a character skinned once per frame, laid out [slot][vertex], two vec4 per
// vertex: (position, 1) and (unit normal, 0), model space, morph targets
// applied. A storage buffer binding holds at most GL_MAX_SHADER_STORAGE_BLOCK_SIZE
// bytes (128 MB on llvmpipe), so a frame's poses are cut into windows of whole
// slots, one buffer each; u_posed_first is the first slot of the bound window.
// Read by the draw of copies (posed.vert) and by compute passes (POSED_WRITE:
// the skinning pass, pose_skin.comp).
#ifndef POSED_BINDING
#define POSED_BINDING 6
#endif
#ifdef POSED_WRITE
layout(std430, binding = POSED_BINDING) writeonly buffer PosedVertices { vec4 posed_data[]; };
#else
layout(std430, binding = POSED_BINDING) readonly buffer PosedVertices { vec4 posed_data[]; };
#endif
uniform int u_posed_vertices;  // vertices per pose
uniform int u_posed_first;     // first slot of the bound window

int posed_at(int slot, int v) { return 2 * ((slot - u_posed_first) * u_posed_vertices + v); }

#ifdef POSED_WRITE
void posed_store(int slot, int v, vec3 p, vec3 n) {
    int at = posed_at(slot, v);
    posed_data[at] = vec4(p, 1.0);
    posed_data[at + 1] = vec4(n, 0.0);
}
#else
void posed_vertex(int slot, int v, out vec3 p, out vec3 n) {
    int at = posed_at(slot, v);
    p = posed_data[at].xyz;
    n = posed_data[at + 1].xyz;
}
#endif
