"""A compute rasteriser for small triangles (issue 29; the split Nanite makes between hardware and software
rasterisation: Karis, Stubbe, Wihlidal, *Nanite, a deep dive*, SIGGRAPH 2021 Advances course).

Why: on Mesa llvmpipe the vertex stage runs on one thread while compute shaders run on every core, and most
triangles of a crowd are smaller than a pixel. A copy whose triangles are estimated below ``[render]
raster_threshold`` pixels (``lod/raster_route.py``) is drawn by compute passes instead of the fixed-function pipeline:

1. vertex pass (``shaders/raster/raster_vertex.glsl``): every used vertex of every copy to window coordinates in fixed
   point with 8 sub-pixel bits (llvmpipe's FIXED_ORDER), pixel centres on integers, its window depth and clip
   outcodes, computed as the hardware path's vertex stage computes them (instance rows, then ``u_view_proj``;
   the viewport transform as llvmpipe's draw module does it);
2. depth pass (``raster_tri.glsl``): a thread per triangle culls it (all vertices outside one clip plane; a back
   face of a single-sided mesh; zero area), sets it aside for the hardware path (a vertex behind the near
   plane, or a window box wider or taller than the threshold), or tests every pixel centre of its box with
   integer edge functions (exact) and llvmpipe's fill rule for GL (a sample on a bottom or left edge belongs
   to the triangle: the top-left rule of the y-down image; measured on llvmpipe, see the tests), interpolates
   the window depth from the exact edge values and does ``atomicMin`` of its float bits (the depth key) per
   pixel. A triangle that lowered a key is listed as a candidate (most triangles of a far crowd own no pixel);
3. id pass: the candidates again, ``atomicMin`` of the triangle id where their depth won (ties: the lowest id,
   whatever order the threads ran in). With ``GL_NV_shader_atomic_int64`` one 64-bit (depth, id) atomic would
   do both; llvmpipe 15 offers no 64-bit atomics, hence the point splat's two-pass scheme;
4. shading pass (``raster_shade.frag``): one fragment per pixel of the tiles the id pass marked reads its
   triangle back, meets it with the pixel-centre ray (perspective-correct barycentrics), interpolates normal and
   tinted colour as the vertex stage feeds the fragment stage, and shades with the same GLSL (``lit_shade.glsl``,
   shared with ``lit.frag``; ``world_light.glsl`` for props and solids; ``tint.glsl``), writing
   ``gl_FragDepth``: the depth test composes the two paths;
5. the set-aside triangles drawn by the hardware (``raster_spill.vert``: vertex pulling from the same tables).

Its tables are textures (``tables``): llvmpipe scalarises a storage-buffer load whose address differs per lane,
while ``texelFetch`` is vectorised; on 100 copies of a 60 K-triangle character the triangle pass took 740 ms of CPU
with storage buffers and 102 ms with textures (a vertex pass reading in order: 122 ms against 65 ms). Work groups
sharing vertices through shared memory (Nanite's cluster layout) measured 5x slower on llvmpipe (its barriers are
coroutine switches). Skinned copies read the pose cache's posed vertices (``render/poses/cache.py``: one slot per
distinct pose, skinned once): read in place from the cache's window when every skinned copy of a window draws one
mesh from one window of the cache (its layout is the rasteriser's posed table's), else gathered by slot into the
rasteriser's own table (``shaders/raster/raster_gather.glsl``);
a copy whose mesh the cache cannot pose this frame stays on the hardware path. A frame above a texture's size or a storage buffer's binding limit (llvmpipe: 128 MB)
is cut into windows of whole copies, each through all passes (``frame``). Not taken by the compute path: MSAA
renderers, geomorphed LOD levels, screen-door transitions, occlusion-culled cluster cuts, point splats' triangles.

Modules, in data-flow order (the routing rule is ``lod/raster_route.py``): ``tables`` (the CPU side of its
textures), ``frame`` (the ``Raster``: uploaded meshes, the gather of posed vertices, the per-frame passes,
windows), ``hook`` (the renderer's, world drawer's and cluster drawer's side: splitting their instances
between the paths).
"""
