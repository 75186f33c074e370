"""Pose sharing, render side: per frame and character the joint palette of each distinct pose and, on request,
the posed vertices of a mesh in the distinct poses its copies draw (issue 29; the LOD side is ``lod/poses``).

One :class:`PoseCache` per renderer (``Renderer.poses``). Each frame, :meth:`PoseCache.begin` takes the
DrawList's :class:`lod.poses.PoseTable` and

- blends the joint palette of every distinct pose of every character once (numba over the poses,
  ``render/poses/skin.py``; at the default key rate a pose is one baked row, so its palette is a copy) and
  uploads them into one RGBA32F texture in the layout of ``render/poses/palette.py`` (:class:`PosePalette`: a
  character's slot ``s`` starts at texel ``base + s * 3J``). The skinned, cluster and chain programs read it
  with the copy's slot (``i_anim.y``, the ``POSE_SLOT`` variants of ``shaders/poses/skinning.glsl``) instead of a
  per-copy palette built by the transform-feedback pre-pass;
- on request (:meth:`PoseCache.posed`: the full-detail drawer, the compute rasteriser) skins the vertices of a
  mesh once in each pose slot the requesting copies read (:class:`PosedVertices`; a slot no copy of that mesh
  reads is not skinned: one agent drawn by a chain level costs one pose, not its character's all): morph
  targets blended first, normals through the
  inverse transpose of the blended matrix. The skinning pass is a compute shader (``shaders/poses/pose_skin.comp``,
  every core on llvmpipe) or numba over both cores (:attr:`PoseCache.skinning`; the faster one is the
  default, scripts/bench_full_detail.md). Copies then draw from the buffer with only their instance transform
  (``shaders/poses/posed.vert``).

Posed-vertex layout (``shaders/poses/posed.glsl``): ``[slot][vertex]`` in one RGBA32F texture of
:data:`POSED_WIDTH` texels per row, two texels per vertex, ``(x, y, z, nx), (ny, nz, 0, 0)`` (position and unit
normal, model space): the compute rasteriser's posed-table layout, so it reads a window in place
(``render/raster/frame.py``); vertex ``v`` of slot ``s`` is texel ``t = 2 (s V + v)`` at ``(t & 4095, t >> 12)``
(a texture, not a storage buffer: on llvmpipe ``texelFetch`` is several times cheaper than per-lane storage-buffer
loads, which it scalarises and bounds-checks; written by ``imageStore``). The slots are cut into *windows* of whole
slots, one texture each, of at most :attr:`PoseCache.window_bytes` (default 128 MB, llvmpipe's storage-block
binding limit: a reader may copy a window into a storage buffer) and of at most ``GL_MAX_TEXTURE_SIZE`` rows;
a reader binds the window of the slots it reads and sets ``u_posed_first`` to the window's first slot
(:meth:`PosedVertices.bind`). Windows are never silently cut short: a pose larger than a window, or posed
vertices beyond :attr:`PoseCache.budget_bytes` in all, make :meth:`posed` return None, and the copies are
skinned in the vertex stage from the pose palettes instead (same pixels). Palettes beyond the palette texture's limit (``render.poses.palette.PALETTE_MAX_TEXELS``)
turn the pose cache off for that frame: every copy through the per-copy pre-pass, at its pose's frame coordinate
(``lod.poses`` writes it into the copy's ``i_anim.x``), so the poses and pixels stay those of the cache.

Nothing non-finite is uploaded: pose frames and palettes are checked (FloatingPointError).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from lod.poses.table import SLOT_FLOAT, mesh_digest
from render.poses.palette import PALETTE_MAX_TEXELS, Palette
from render.poses.skin import POSED_FLOATS, blend_palettes, skin_poses
from render.shaders import load_source
from render.poses.targets import TARGETS_DEFINE, use_targets
from render.vertex_format import compact_influences

#: texels per row of the posed-vertex and mesh textures (``shaders/poses/posed.glsl``: texel t at (t & 4095, t >> 12))
POSED_WIDTH = 4096
#: texels per posed vertex: (x, y, z, nx), (ny, nz, 0, 0) (``shaders/poses/posed.glsl``, raster_common.glsl RS_POSED)
POSED_TEXELS = 2
#: texture unit the readers sample the posed vertices from (``u_posed``)
POSED_UNIT = 8
#: texture units of the skinning pass's mesh tables (``u_bind``, ``u_skin_joints``)
BIND_UNIT = 10
JOINTS_UNIT = 11
#: bytes per posed vertex (its two texels)
POSED_VERTEX_BYTES = 16 * POSED_TEXELS
#: most bytes of one window (its texture); llvmpipe's GL_MAX_SHADER_STORAGE_BLOCK_SIZE, so that a window
#: also fits one storage-buffer binding
POSED_WINDOW_BYTES = 128 * 1024 * 1024
#: most bytes of posed vertices of one mesh in one frame (beyond: the copies skin from the palettes)
POSED_BUDGET_BYTES = 1024 * 1024 * 1024
#: skinning passes: "compute" (shaders/poses/pose_skin.comp) or "numba" (render/poses/skin.py)
SKINNING_PASSES = ("compute", "numba")
#: default skinning pass (scripts/bench_full_detail.md "pose skinning": compute vs numba)
SKINNING_PASS = "compute"
#: invocations per work group of the compute skinning pass
SKIN_LOCAL_SIZE = 64
#: most work groups along y in one dispatch (GL's guaranteed minimum)
MAX_GROUPS_Y = 65535
#: texture unit of the pose palettes (skinning.glsl u_palette)
PALETTE_UNIT = 1
#: vec4 of the skinning pass's palette uniform block (64 KB, GL's guaranteed GL_MAX_UNIFORM_BLOCK_SIZE): the
#: pass reads the palettes of at most this / 3J slots per dispatch from it (llvmpipe: 1.3x faster than texels,
#: h4 with 100 poses); characters with more than 1,365 joints read the palette texture
PALETTE_UBO_VEC4 = 4096


@dataclass
class PosePalette:
    """The palettes of one character's distinct poses this frame (a block of the pose-palette texture).

    texture : RGBA32F texture, ``render.poses.palette`` layout; base : first texel of slot 0; stride : texels per
    pose (3 x joints); frames : (P,) frame coordinates of the poses (slot order); palettes : (P, J, 3, 4)
    float32, the same values on the CPU
    """

    texture: object
    base: int
    stride: int
    frames: np.ndarray
    palettes: np.ndarray

    @property
    def n_poses(self) -> int:
        return int(self.frames.shape[0])

    def use(self, prog, unit: int = PALETTE_UNIT) -> None:
        """Bind the texture to ``unit`` and point ``prog``'s palette uniforms at this character's block."""
        self.texture.use(unit)
        for name, value in (("u_palette", unit), ("u_palette_base", self.base), ("u_palette_stride", self.stride)):
            if name in prog:
                prog[name].value = value


@dataclass
class PosedWindow:
    """Slots ``first .. first + count`` of a mesh's posed vertices: texels 0 and 1 of ``texture`` (RGBA32F,
    :data:`POSED_WIDTH` wide, at least ``rows`` rows) are the first slot's vertex 0."""

    first: int
    count: int
    texture: object
    rows: int


@dataclass
class PosedVertices:
    """A mesh's vertices in every distinct pose of its character this frame (``shaders/poses/posed.glsl``).

    group : character (pose group); vertices : per pose; windows : PosedWindow list, consecutive slot ranges
    """

    group: str
    vertices: int
    windows: list
    poses: int
    #: (poses,) bool: the slots skinned this frame (a mesh is skinned only in the slots its copies draw)
    done: np.ndarray | None = None

    @property
    def slots_per_window(self) -> int:
        return int(self.windows[0].count) if self.windows else 1

    def window_of(self, slots) -> np.ndarray:
        """Window index of each slot."""
        return np.asarray(slots, np.int64) // self.slots_per_window

    def runs(self, slots, first: int, count: int) -> list:
        """``[(first, count, window), ...]``: copies ``first .. first + count`` (slots ``slots``, all copies of
        the batch) cut into runs of consecutive copies whose slots lie in one window."""
        if len(self.windows) == 1 or count <= 0:
            return [(first, count, 0)] if count > 0 else []
        w = self.window_of(np.asarray(slots[first:first + count]).round())
        cut = np.concatenate([[0], np.flatnonzero(np.diff(w)) + 1, [count]])
        return [(first + int(a), int(e - a), int(w[a])) for a, e in zip(cut[:-1], cut[1:])]

    def bind(self, w: int, prog=None, unit: int = POSED_UNIT) -> None:
        """Bind window ``w``'s texture to ``unit`` and set ``prog``'s sampler ``u_posed``, ``u_posed_vertices``
        and ``u_posed_first`` (``shaders/poses/posed.glsl``)."""
        win = self.windows[w]
        win.texture.use(unit)
        if prog is not None:
            for name, value in (("u_posed", unit), ("u_posed_vertices", self.vertices), ("u_posed_first", win.first)):
                if name in prog:
                    prog[name].value = value

    def read(self) -> np.ndarray:
        """(P, V, 8) float32 of every window read back: position, 1, normal, 0 (tests, debugging)."""
        out = np.zeros((self.poses, self.vertices, POSED_FLOATS), np.float32)
        for w in self.windows:
            n = w.count * self.vertices
            raw = np.frombuffer(w.texture.read(), np.float32).reshape(-1, 2 * 4)[:n].reshape(w.count, self.vertices, 8)
            out[w.first:w.first + w.count] = from_texels(raw)
        return out


@dataclass
class _Mesh:
    """A mesh the pose cache can pose: CPU arrays, and its skinning-pass textures once first posed."""

    digest: str
    positions: np.ndarray
    normals: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    n_inf: int
    targets: object
    joint_texture: object
    target_textures: object
    gpu: list = field(default_factory=list)  # the skinning pass's tables: bind (RGBA32F), joints (RGBA32UI)
    windows: list = field(default_factory=list)  # window textures kept from frame to frame

    @property
    def n_vertices(self) -> int:
        return int(self.positions.shape[0])


class PoseCache:
    """Pose palettes and posed vertices of a renderer, frame by frame (module docstring).

    Attributes
    ----------
    skinning : "compute" or "numba", the posed-vertex pass
    window_bytes : most bytes per window, both textures (and at most GL_MAX_TEXTURE_SIZE rows)
    budget_bytes : most posed bytes of one mesh per frame
    last_stats : dict of the last frame: "poses", "posed_vertices", "palette_ms", "skin_ms", "windows",
        "fallback" (meshes skinned per copy from the palettes because their poses exceed the budget)
    """

    def __init__(self, renderer):
        self.r = renderer
        self.ctx = renderer.ctx
        self.skinning = SKINNING_PASS
        self.window_bytes = POSED_WINDOW_BYTES
        self.budget_bytes = POSED_BUDGET_BYTES
        self.available = int(getattr(self.ctx, "version_code", 0)) >= 430  # compute shaders, storage buffers
        self._objects: list = []
        self._palette = Palette(self.ctx, self._track, self._untrack)
        self._meshes: dict = {}  # digest -> _Mesh
        self._rep_mesh: dict = {}  # rep key -> digest
        self._programs: dict = {}
        self._frames = None  # storage buffer of pose frames (morph targets in the compute pass)
        self._ubo = None  # the palettes again, as the skinning pass's uniform block
        self._table = None
        self._pal: dict = {}  # group -> PosePalette
        self._posed: dict = {}  # (group, digest) -> PosedVertices or None
        self.last_stats: dict = {}

    # ------------------------------------------------------------------ resources
    def _track(self, obj, label: str):
        from render.context import track

        return track(self._objects, obj, label)

    def _untrack(self, obj) -> None:
        if obj in self._objects:
            self._objects.remove(obj)

    def note_rep(self, rep, joint_texture=None, target_textures=None) -> None:
        """Remember a skinned rep's mesh (called by ``Renderer.upload``); reps with the same mesh share it."""
        if getattr(rep, "kind", None) != "skinned" or not hasattr(rep, "joint_table"):
            self._rep_mesh.pop(getattr(rep, "key", None), None)
            return
        d = mesh_digest(rep)
        self._rep_mesh[rep.key] = d
        m = self._meshes.get(d)
        if m is not None:  # the newest upload's tables (an earlier rep's may have been released)
            m.joint_texture, m.target_textures = joint_texture, target_textures
        else:
            jn, wt, n_inf = compact_influences(rep.joints, rep.weights)
            self._meshes[d] = _Mesh(d, np.ascontiguousarray(rep.positions, np.float32),
                                    np.ascontiguousarray(rep.normals, np.float32), np.ascontiguousarray(jn),
                                    np.ascontiguousarray(wt, np.float32), int(n_inf), getattr(rep, "targets", None),
                                    joint_texture, target_textures)

    def release(self) -> None:
        for m in self._meshes.values():
            for b in m.gpu + [w for w in m.windows if w is not None]:
                b.release()
            m.gpu, m.windows = [], []
        for o in reversed(self._objects):
            o.release()
        self._objects.clear()
        self._programs.clear()
        self._frames = self._ubo = None

    # ------------------------------------------------------------------ frame
    def begin(self, table) -> None:
        """Start a frame with ``table`` (a ``lod.poses.PoseTable``, or None: no pose sharing this frame):
        blend and upload the palettes of every group's distinct poses."""
        t0 = time.perf_counter()
        self._table, self._pal, self._posed = None, {}, {}
        self.last_stats = {"poses": 0, "posed_vertices": 0, "palette_ms": 0.0, "skin_ms": 0.0, "windows": 0,
                           "fallback": 0}
        if table is None or not self.available or not table.sets:
            return
        blocks, base = [], 0
        for gk, ps in table.sets.items():
            frames = np.asarray(ps.frames, np.float64)
            if not np.isfinite(frames).all():
                raise FloatingPointError(f"pose table of {gk!r}: a pose's frame coordinate is NaN or Inf")
            pal = blend_palettes(ps.group.source.joint_table, frames)
            stride = 3 * int(pal.shape[1])
            self._pal[gk] = PosePalette(None, base, stride, frames, pal)
            blocks.append(pal.reshape(-1, 4))
            base += pal.shape[0] * stride
        if base > PALETTE_MAX_TEXELS:  # beyond the palette texture: every copy through the per-copy pre-pass
            self._pal = {}
            self.last_stats["fallback"] = len(table.sets)
            return
        texels = np.concatenate(blocks) if len(blocks) > 1 else blocks[0]
        if not np.isfinite(texels).all():
            raise FloatingPointError("pose palettes hold NaN or Inf (a joint table is not finite)")
        self._palette.upload(texels)
        if self._ubo is None or self._ubo.size < texels.nbytes + 16 * PALETTE_UBO_VEC4:  # a full block past the end
            if self._ubo is not None:
                self._ubo.release()
                self._untrack(self._ubo)
            self._ubo = self._track(self.ctx.buffer(reserve=2 * texels.nbytes + 16 * PALETTE_UBO_VEC4),
                                    "poses.palette_block")
        self._ubo.write(texels.tobytes())
        for p in self._pal.values():
            p.texture = self._palette.texture
        self._table = table
        self.last_stats["poses"] = int(sum(p.n_poses for p in self._pal.values()))
        self.last_stats["palette_ms"] = 1e3 * (time.perf_counter() - t0)

    def group_of(self, rep_key: str):
        """The pose group (character) drawing ``rep_key`` this frame, or None."""
        return None if self._table is None else self._table.rep_group.get(rep_key)

    def palette(self, rep_key: str):
        """The :class:`PosePalette` of the character ``rep_key`` draws, or None (no pose table this frame)."""
        g = self.group_of(rep_key)
        return None if g is None else self._pal.get(g)

    def posed(self, rep_key: str, mesh_key: str | None = None, slots=None):
        """The :class:`PosedVertices` of skinned rep ``rep_key``'s mesh (or of the uploaded skinned rep
        ``mesh_key``'s: a clusters rep's full-detail mesh) in the distinct poses of ``rep_key``'s character,
        or None: no pose table, not a mesh the cache knows, or poses beyond a window or the budget (the caller
        skins per copy from :meth:`palette`). ``slots``: the pose slots the caller's copies read (instance
        float ``SLOT_FLOAT``); only those not skinned yet this frame are skinned (None: every slot). A mesh
        drawn by one copy is then skinned in one pose, not in all the character's: the exhibition's auto drew
        one agent's chain level and posed it in 33 poses, 1.4 M vertices, a 140 ms frame (issue 49)."""
        g = self.group_of(rep_key)
        d = self._rep_mesh.get(rep_key if mesh_key is None else mesh_key)
        if g is None or d is None or g not in self._pal:
            return None
        return self._skin(g, self._meshes[d], slots)

    def posing_cost(self, rep_key: str, mesh_key: str | None = None, slots=None) -> int | None:
        """Vertices :meth:`posed` would skin for this request now (0: skinned already this frame, or it cannot
        be posed), None when it would give None for want of a pose table or a mesh the cache knows. Skins
        nothing: a caller weighing a route prices the pass before asking for it."""
        g = self.group_of(rep_key)
        d = self._rep_mesh.get(rep_key if mesh_key is None else mesh_key)
        if g is None or d is None or g not in self._pal:
            return None
        have = self._posed.get((g, d), False)
        if have is None or (have is not False and have.done.all()):
            return 0
        P = int(self._pal[g].n_poses)
        need = self._need(P, have.done if have is not False else None, slots)
        return int(need.sum()) * int(self._meshes[d].n_vertices)

    @staticmethod
    def _need(P: int, done, slots) -> np.ndarray:
        """(P,) bool: the slots of ``slots`` (None: all) not in ``done`` (None: none done)."""
        if slots is None:
            need = np.ones(P, bool)
        else:
            need = np.zeros(P, bool)
            s = np.asarray(slots, np.float64).reshape(-1)
            s = s[np.isfinite(s)].round().astype(np.int64)
            need[s[(s >= 0) & (s < P)]] = True
        return need if done is None else need & ~done

    def _limit(self) -> int:
        """Most vertices of one window: :attr:`window_bytes` and the texture's rows."""
        rows = int(self.ctx.info.get("GL_MAX_TEXTURE_SIZE") or 16384)
        return max(1, min(int(self.window_bytes) // POSED_VERTEX_BYTES, POSED_WIDTH * rows // POSED_TEXELS))

    def _skin(self, group: str, mesh: _Mesh, slots=None):
        """The frame's :class:`PosedVertices` of ``mesh`` in ``group``'s poses (made on the first request), with
        the slots ``slots`` (None: all) skinned; None when the poses do not fit (see :meth:`posed`)."""
        t0 = time.perf_counter()
        key = (group, mesh.digest)
        pal = self._pal[group]
        P, V = pal.n_poses, mesh.n_vertices
        posed = self._posed.get(key, False)
        if posed is None:
            return None
        if posed is not False and posed.done.all():  # every slot skinned: each later request of the frame is free
            return posed
        if posed is False:
            if V == 0 or V > self._limit() or P * V * POSED_VERTEX_BYTES > self.budget_bytes:
                self.last_stats["fallback"] += 1
                self._posed[key] = None
                return None
            spw = max(1, self._limit() // V)
            windows = []
            for i, first in enumerate(range(0, P, spw)):
                n = min(spw, P - first)
                rows = -(-n * V * POSED_TEXELS // POSED_WIDTH)
                windows.append(PosedWindow(first, n, self._window_texture(mesh, i, rows), rows))
            posed = self._posed[key] = PosedVertices(group, V, windows, P, np.zeros(P, bool))
            self.last_stats["windows"] += len(windows)
        need = self._need(P, posed.done, slots)
        if not need.any():
            return posed
        if self.skinning == "numba":  # whole windows written at once: every slot left
            need = ~posed.done
            out = skin_poses(mesh.positions, mesh.normals, mesh.joints[:, :mesh.n_inf], mesh.weights[:, :mesh.n_inf],
                             pal.palettes, mesh.targets, pal.frames)
            for w in posed.windows:
                full = np.zeros((w.rows * POSED_WIDTH // POSED_TEXELS, 4 * POSED_TEXELS), np.float32)
                part = to_texels(out[w.first:w.first + w.count].reshape(-1, POSED_FLOATS))
                full[:part.shape[0]] = part
                w.texture.write(full.tobytes(), viewport=(0, 0, POSED_WIDTH, w.rows))
        else:
            self._skin_compute(mesh, pal, posed, need)
        posed.done |= need
        self.last_stats["skin_ms"] += 1e3 * (time.perf_counter() - t0)
        self.last_stats["posed_vertices"] += int(need.sum()) * V
        return posed

    def _window_texture(self, mesh: _Mesh, i: int, rows: int):
        """The texture of window ``i`` of ``mesh`` with at least ``rows`` rows (kept across frames, re-made when
        a frame needs more rows)."""
        while len(mesh.windows) <= i:
            mesh.windows.append(None)
        have = mesh.windows[i]
        if have is None or have.height < rows:
            if have is not None:
                have.release()
            have = self._texture((POSED_WIDTH, rows), 4, "f4", f"poses.{mesh.digest[:8]}.window{i}")
            mesh.windows[i] = have
        return have

    def _texture(self, size, components: int, dtype: str, label: str, data=None):
        import moderngl

        t = self.ctx.texture(size, components, data, dtype=dtype)
        t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        t.repeat_x = t.repeat_y = False
        t.label = label
        return t

    def shared(self, b):
        """How the skinned batch ``b`` draws from the pose cache this frame: ``("posed", PosedVertices)``,
        ``("palette", PosePalette)`` (its mesh cannot be posed within the limits, or it is a geomorphed chain
        level: skinned per copy from the pose palettes), or None (no pose palette: the per-copy pre-pass)."""
        pal = self.palette(b.rep) if self._pal else None
        if pal is None:
            return None
        posed = None if getattr(b, "morph", None) is not None else self.posed(
            b.rep, slots=np.asarray(b.instance_data)[:, SLOT_FLOAT])
        return ("palette", pal) if posed is None else ("posed", posed)

    def plan(self, batches, reps: dict) -> list:
        """Skin the posed vertices the frame's skinned batches draw from (before anything is drawn) and return
        the batches, one whose copies' slots span several posed windows replaced by a copy sorted by window
        (stable), so that it draws in one run per window.

        batches : the renderer's triangle batches; reps : rep key -> the renderer's ``_GpuRep``
        """
        if not self._pal:
            return batches
        out = []
        for b in batches:
            g = reps.get(b.rep)
            how = self.shared(b) if g is not None and g.kind == "skinned" and g.n_indices else None
            if how is not None and how[0] == "posed" and len(how[1].windows) > 1:
                w = how[1].window_of(np.asarray(b.instance_data[:, SLOT_FLOAT]).round())
                if (np.diff(w) < 0).any():
                    order = np.argsort(w, kind="stable")
                    b = replace(b, instance_ids=np.asarray(b.instance_ids)[order],
                                instance_data=np.asarray(b.instance_data)[order])
            out.append(b)
        return out

    # ------------------------------------------------------------------ compute pass
    def _program(self, mesh: _Mesh, ubo: bool):
        defines = [f"LOCAL_SIZE {SKIN_LOCAL_SIZE}"] + ([f"PALETTE_UBO {PALETTE_UBO_VEC4}"] if ubo else [])
        if mesh.n_inf < 4:
            defines.append(f"SKIN_INFLUENCES_{mesh.n_inf}")
        if mesh.targets is not None and mesh.target_textures is not None:
            defines.append(TARGETS_DEFINE)
        key = tuple(defines)
        if key not in self._programs:
            src = load_source("pose_skin.comp")
            lines = src.split("\n", 1)
            src = lines[0] + "\n" + "".join(f"#define {d}\n" for d in defines) + lines[1]
            self._programs[key] = self._track(self.ctx.compute_shader(src), "poses.compute.pose_skin")
        return self._programs[key]

    def _mesh_textures(self, mesh: _Mesh) -> list:
        """(bind, joints) textures of the skinning pass (``shaders/poses/pose_skin.comp``), made on first use."""
        if not mesh.gpu:
            n = mesh.n_vertices
            bind = np.zeros((n, 3, 4), np.float32)
            bind[:, 0, :3] = mesh.positions
            bind[:, 0, 3] = 1.0
            bind[:, 1, :3] = mesh.normals
            bind[:, 2, :mesh.weights.shape[1]] = mesh.weights
            jn = np.zeros((n, 4), np.uint32)
            jn[:, :mesh.joints.shape[1]] = mesh.joints
            for a, dtype, what in ((bind.reshape(-1, 4), "f4", "bind"), (jn, "u4", "joints")):
                rows = max(1, -(-a.shape[0] // POSED_WIDTH))
                full = np.zeros((rows * POSED_WIDTH, 4), a.dtype)
                full[:a.shape[0]] = a
                mesh.gpu.append(self._texture((POSED_WIDTH, rows), 4, dtype, f"poses.{mesh.digest[:8]}.{what}",
                                              full.tobytes()))
        return mesh.gpu

    def _skin_compute(self, mesh: _Mesh, pal: PosePalette, posed: PosedVertices, need) -> None:
        """Skin the slots ``need`` ((P,) bool) of ``posed``: one dispatch per run of consecutive slots in a window
        (at most :data:`MAX_GROUPS_Y` slots, or the palettes the uniform block holds)."""
        ctx = self.ctx
        per_block = PALETTE_UBO_VEC4 // pal.stride  # slots whose palettes fit the uniform block
        prog = self._program(mesh, per_block > 0)
        bind, joints = self._mesh_textures(mesh)
        bind.use(BIND_UNIT)
        joints.use(JOINTS_UNIT)
        prog["u_bind"].value = BIND_UNIT
        prog["u_skin_joints"].value = JOINTS_UNIT
        frames = np.ascontiguousarray(pal.frames, np.float32)
        if self._frames is None or self._frames.size < frames.nbytes:
            if self._frames is not None:
                self._frames.release()
                self._untrack(self._frames)
            self._frames = self._track(ctx.buffer(reserve=max(4096, 2 * frames.nbytes)), "poses.frames")
        self._frames.write(frames.tobytes())
        self._frames.bind_to_storage_buffer(4)
        if mesh.joint_texture is not None:
            mesh.joint_texture.use(0)
            if "u_joints" in prog:
                prog["u_joints"].value = 0
        pal.use(prog)
        if mesh.targets is not None and mesh.target_textures is not None:
            use_targets(prog, mesh.target_textures)
        gx = -(-posed.vertices // SKIN_LOCAL_SIZE)
        prog["u_posed_vertices"].value = posed.vertices
        step = min(MAX_GROUPS_Y, per_block) if per_block > 0 else MAX_GROUPS_Y
        for win in posed.windows:
            idx = np.flatnonzero(need[win.first:win.first + win.count]) + win.first
            if not idx.size:
                continue
            prog["u_posed_first"].value = win.first
            win.texture.bind_to_image(0, read=False, write=True)
            for y0, n in slot_runs(idx, step):
                if per_block > 0:  # this dispatch's palettes as the uniform block (16-byte aligned offsets)
                    self._ubo.bind_to_uniform_block(0, offset=16 * (pal.base + y0 * pal.stride),
                                                    size=16 * PALETTE_UBO_VEC4)
                    prog["u_ubo_first"].value = y0
                prog["u_slot_start"].value = y0
                prog.run(gx, n, 1)
        ctx.memory_barrier()


def to_texels(rows: np.ndarray) -> np.ndarray:
    """(n, 8) rows position, 1, normal, 0 (``render.poses.skin``) -> (n, 8) texel pairs (x, y, z, nx, ny, nz, 0, 0)."""
    out = np.zeros_like(rows, dtype=np.float32)
    out[:, :3] = rows[:, :3]
    out[:, 3:6] = rows[:, 4:7]
    return out


def from_texels(texels: np.ndarray) -> np.ndarray:
    """The inverse of :func:`to_texels` (any leading shape): position, 1, normal, 0."""
    out = np.zeros_like(texels, dtype=np.float32)
    out[..., :3] = texels[..., :3]
    out[..., 3] = 1.0
    out[..., 4:7] = texels[..., 3:6]
    return out


def slot_runs(idx, step: int) -> list:
    """``[(first slot, count), ...]``: the sorted slots ``idx`` as runs of consecutive slots, none longer than
    ``step``."""
    idx = np.asarray(idx, np.int64)
    if not idx.size:
        return []
    cut = np.flatnonzero(np.diff(idx) != 1) + 1
    out = []
    for a, e in zip(np.concatenate([[0], cut]), np.concatenate([cut, [idx.size]])):
        first, last = int(idx[a]), int(idx[e - 1])
        out.extend((y0, min(step, last + 1 - y0)) for y0 in range(first, last + 1, step))
    return out


__all__ = ["POSED_TEXELS", "POSED_UNIT", "POSED_WIDTH", "POSED_BUDGET_BYTES", "POSED_VERTEX_BYTES", "POSED_WINDOW_BYTES", "SKINNING_PASSES",
           "PoseCache", "PosePalette", "PosedVertices", "PosedWindow", "mesh_digest", "slot_runs"]
