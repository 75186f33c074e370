"""Memory estimate of a scene and the guard that refuses scenes too big for the machine.

The estimate is made *before* the big allocations: agent counts come from the
validated placement parameters (never from building them) plus what the
``[[sources]]`` can add during the run (``crowd.scene_journeys.entering_agents``), characters from
their specs (generator triangle counts, glTF file sizes) or, when they are
already built, from their meshes and clips. It adds up

- ``runtime``: the process before any scene data (:data:`RUNTIME_BYTES`);
- ``state``: the ``CrowdState`` arrays (78 bytes per agent) plus the working
  arrays of the simulation steps (:data:`SIM_SCRATCH_PER_AGENT`);
- ``selection``: one frame's DrawList (instance data (n, 16) float32, ids)
  and the selector's per-agent scratch (:data:`SELECT_BYTES_PER_AGENT`);
- ``characters``: meshes and, for skinned characters, the joint tables baked
  at the character's ``fps`` (``(frames, joints, 3, 4)`` float32 per clip);
- ``gpu``: the instance buffer (capacity doubles, so up to 2x), vertex
  buffers and joint textures of every representation, the skinning palette
  (3 texels of 16 bytes per joint per visible skinned instance, buffer and
  texture) and the framebuffer;
- ``driver``: the GL driver's binned triangles (Mesa llvmpipe keeps each
  36 MB "scene" of binned triangle data until it reuses it; the renderer
  waits after every :data:`render.renderer.MAX_TRIANGLES_IN_FLIGHT`
  triangles, so a few scenes are ever in use): triangles per frame at full
  detail x :data:`BINNED_BYTES_PER_TRIANGLE`, capped at
  :data:`DRIVER_SCENES` scenes of :data:`DRIVER_SCENE_BYTES`;
- ``lod``: the LOD mode's hierarchies (:data:`LOD_BYTES_PER_TRIANGLE`, or the
  mode module's own ``memory_estimate(characters_or_specs, params) -> int``
  bytes when it has one).

Measured against the peak resident memory of ``crowd run --frames 2`` the
estimate was 0.86x-1.19x of it on six scenes (table in scripts/soak.md);
tests/crowd/test_memory_guard.py checks a small scene within a factor 1.6.

The guard compares the total with ``MemAvailable`` of ``/proc/meminfo``
(fallback: ``os.sysconf`` physical pages; unknown: no refusal).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

from crowd.errors import SceneError

#: bytes of CrowdState per agent: position, velocity (3 float64 each), heading,
#: anim_time (float64), scale, anim_rate (float32), character (int32), clip (int16)
STATE_BYTES_PER_AGENT = 3 * 8 + 3 * 8 + 8 + 4 + 4 + 2 + 8 + 4
#: working arrays of the simulation steps per agent (grid keys, sort order,
#: neighbour forces: a conservative multiple of the state)
SIM_SCRATCH_PER_AGENT = 3 * STATE_BYTES_PER_AGENT
#: one frame's selection per agent: instance data 64 B + id 4 B, and the
#: selector's float64/int64 scratch (group id, time, anim, visibility, order)
SELECT_BYTES_PER_AGENT = 64 + 4 + 6 * 8
#: mode auto prices every candidate per agent on top: the flat rows of lod/auto/flat.py (per candidate the
#: cheapest option, its column, the skipped flags: 3 x 17 B), the point candidate's sorted copy of the instance
#: data with its segments, jobs and totals (~200 B), the plans' choices (4 x 8 B); measured on scenes/million.toml,
#: peak 1.24 GB against 1.03 GB in mode points for a million agents (scripts/bench_million.md; the per-group path
#: it replaced peaked at 1.36 GB), so 400 B per agent over-counts a little
AUTO_SELECT_BYTES_PER_AGENT = 400
#: GPU instance data per agent (16 float32), times 2 for capacity doubling
GPU_INSTANCE_BYTES = 64 * 2
#: bytes per vertex of a skinned representation on the CPU and again on the GPU:
#: position, normal (12 each), colour (16), joints (8), weights (16)
VERTEX_BYTES = 12 + 12 + 16 + 8 + 16
#: bytes per triangle (3 uint32 indices)
TRIANGLE_BYTES = 12
#: skinning palette cap (texels): the palette is built and drawn in chunks of at most this many texels,
#: as render.poses.palette.PALETTE_CHUNK_TEXELS (so its memory does not grow with the crowd)
PALETTE_MAX_TEXELS = 1 << 22
#: a glTF file's bytes are multiplied by this to estimate the loaded character
#: (float64 working copies while importing)
GLTF_EXPANSION = 4
#: assumed skeleton size and clip length of a generated character (estimate before building)
GENERATOR_JOINTS = 64
GENERATOR_CLIP_SECONDS = 2.0
GENERATOR_CLIPS = 4
#: CPU bytes per character triangle of a LOD mode's representations beyond the
#: full-detail rep (hierarchies), measured on a 5,000-triangle humanoid with the
#: default [lod] parameters (clusters: ~71 B, points: ~16 kB: point samples of
#: every keyframe segment); a mode's own ``memory_estimate`` replaces it
LOD_BYTES_PER_TRIANGLE = {"none": 0, "clusters": 80, "points": 16_500}
#: bytes of a glTF file per triangle (used before the file is loaded)
GLTF_BYTES_PER_TRIANGLE = 40
#: the process before any scene data: interpreter, numpy, numba kernels, the GL
#: context and compiled shaders; measured peak resident 273 MB for
#: scenes/poser4.toml (4 agents) with ``crowd run --frames 2``
RUNTIME_BYTES = 270_000_000
#: bytes of one llvmpipe scene (``LP_SCENE_MAX_SIZE`` of Mesa's lp_scene.h)
DRIVER_SCENE_BYTES = 36 * 1024 * 1024
#: llvmpipe scenes a frame keeps at most with the renderer's split of large
#: draws (one binning, one rasterizing, one for state flushes)
DRIVER_SCENES = 3
#: binned bytes per drawn triangle, averaged over culled, sub-pixel and
#: multi-tile triangles (fitted: quickstart 500 k triangles/frame ~20 MB,
#: office 16 M ~50 MB, horses 58 M ~80 MB of resident memory beyond the rest)
BINNED_BYTES_PER_TRIANGLE = 100
#: fraction of MemAvailable a scene may use
MEMORY_FRACTION = 0.9
#: environment variable overriding the available bytes (tests, CI machines)
MEMORY_ENV = "CROWD_MEMORY_LIMIT"


@dataclass
class MemoryEstimate:
    """Estimated bytes of a scene, by part.

    agents : int, number of agents
    parts : dict name -> bytes ("state", "selection", "characters", "gpu", ...)
    """

    agents: int
    parts: dict = field(default_factory=dict)
    #: (bytes, one clause naming what needs them and the remedy), for the refusal's message (largest first)
    causes: list = field(default_factory=list)

    @property
    def total(self) -> int:
        return int(sum(self.parts.values()))

    def line(self) -> str:
        """One line: total and the parts, e.g. ``memory estimate: 1.2 GB (state 10 MB, ...)``."""
        return (f"memory estimate: {human_bytes(self.total)} ("
                + ", ".join(f"{k} {human_bytes(v)}" for k, v in self.parts.items()) + ")")


def human_bytes(n: float) -> str:
    """``1536`` -> ``"1.5 kB"`` (decimal units)."""
    n = float(n)
    for unit in ("B", "kB", "MB", "GB", "TB", "PB", "EB"):
        if abs(n) < 1000.0 or unit == "EB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n:.1f} EB"  # pragma: no cover


def placement_agents(kind: str, params: dict) -> int:
    """Agents a validated placement will create, without building it."""
    if kind == "grid":
        return int(params["rows"]) * int(params["cols"])
    if kind == "random":
        return int(params["count"])
    if kind == "list":
        return len(params.get("positions") or [])
    if kind == "trajectories":  # at most every recorded person at once
        rec = params.get("recording")
        return 0 if rec is None else int(rec.persons)
    if kind == "hierarchy":
        from sim.instancing import parse_levels

        total = 1
        for cfg in parse_levels(params["levels"], "levels"):
            lay = cfg["layout"]
            if lay == "grid":
                total *= int(cfg["nx"]) * int(cfg["nz"])
            elif lay == "tiers":
                total *= int(cfg["rows"]) * int(cfg["seats_per_row"])
            else:
                total *= len(cfg["children"])
        return total
    raise ValueError(f"placement_agents: unknown placement kind {kind!r}")


def character_bytes(character, fps: float) -> tuple[int, int]:
    """(CPU bytes, GPU bytes) of a built character and its full-detail representation."""
    if character.kind == "skinned":
        m = character.mesh
        mesh = m.n_vertices * VERTEX_BYTES + m.n_triangles * TRIANGLE_BYTES
        from lod.full.reps import bake_intervals  # the frames build_rep bakes (long clips at a lower rate)

        durations = [float(c.duration) for c in character.clips.values()]
        frames = int((bake_intervals(durations, fps) + 1).sum()) if durations else 0
        table = frames * character.skeleton.n_joints * 48
        mt = getattr(m, "morph", None)
        if mt is None:
            return 2 * mesh + 2 * table, mesh + table  # mesh + rep copy; table + per-frame bounds
        # morph targets: dense deltas on the CPU; on the GPU at most every moved (vertex, target) pair
        # (lod.full.targets: 32 bytes each), 8 bytes per vertex and 4 per target and frame
        pairs = int(((mt.positions != 0).any(2) | (mt.normals != 0).any(2)).sum())
        gpu = pairs * 32 + m.n_vertices * 8 + frames * mt.n_targets * 4
        return 2 * mesh + 2 * table + int(mt.positions.nbytes + mt.normals.nbytes) + gpu, mesh + table + gpu
    total = 0
    for a in character.animations.values():
        for s in a.segments:
            total += int(s.src.shape[0]) * 2 * (12 + 12 + 16) + int(s.indices.nbytes)
        for k in a.keyframes:
            total += int(k.positions.nbytes + k.normals.nbytes + k.colors.nbytes + k.indices.nbytes)
    return 2 * total, total


def spec_bytes(spec) -> tuple[int, int]:
    """(CPU bytes, GPU bytes) of a character from its spec, before building it."""
    if spec.generator is not None:
        tri = int(spec.triangles or 5000)
        mesh = (tri // 2 + 2) * VERTEX_BYTES + tri * TRIANGLE_BYTES
        frames = GENERATOR_CLIPS * (int(round(GENERATOR_CLIP_SECONDS * spec.fps)) + 1) + \
            int(round(float(getattr(spec, "dance", 0.0)) * spec.fps))
        table = frames * GENERATOR_JOINTS * 48
        return 2 * mesh + 2 * table, mesh + table
    try:
        size = os.path.getsize(spec.file)
    except OSError:
        size = 0
    return GLTF_EXPANSION * size, size


def estimate_scene(scene, characters=None) -> MemoryEstimate:
    """Estimate the memory a run of ``scene`` needs.

    Parameters
    ----------
    scene : crowd.scene.Scene (validated)
    characters : optional list of built characters aligned with
        ``scene.characters``; without them the specs are used.

    Returns
    -------
    MemoryEstimate
    """
    from crowd.scene_journeys import entering_agents

    entering = entering_agents(scene)  # agents [[sources]] add during the run (exits ignored: an upper bound)
    n = sum(placement_agents(p.kind, p.params) for p in scene.placements) + sum(k for _, k in entering)
    parts = {"runtime": RUNTIME_BYTES,
             "state": n * (STATE_BYTES_PER_AGENT + SIM_SCRATCH_PER_AGENT),
             "selection": n * (SELECT_BYTES_PER_AGENT + (AUTO_SELECT_BYTES_PER_AGENT if scene.lod_mode == "auto"
                                                         else 0))}
    cpu = gpu = 0
    joints = []
    for i, spec in enumerate(scene.characters):
        if characters is not None:
            c, g = character_bytes(characters[i], spec.fps)
            joints.append(characters[i].skeleton.n_joints if characters[i].kind == "skinned" else 0)
        else:
            c, g = spec_bytes(spec)
            joints.append(GENERATOR_JOINTS if spec.generator is not None else 0)
        cpu += c
        gpu += g
    parts["characters"] = cpu
    # palette: 3 texels x 16 B per joint per visible skinned instance, buffer + texture, one chunk at most
    max_joints = max(joints, default=0)
    palette = 2 * 16 * min(PALETTE_MAX_TEXELS, n * 3 * max_joints)
    w, h = scene.render.size
    parts["gpu"] = n * GPU_INSTANCE_BYTES + gpu + palette + w * h * 8 + w * h * 3
    chars = characters if characters is not None else [None] * len(scene.characters)
    tris = sum(placement_agents(p.kind, p.params) * _triangles(scene.characters[p.character], chars[p.character])
               for p in scene.placements) + sum(k * _triangles(scene.characters[c], chars[c]) for c, k in entering)
    parts["driver"] = min(tris * BINNED_BYTES_PER_TRIANGLE, DRIVER_SCENES * DRIVER_SCENE_BYTES)
    if getattr(scene, "props", ()):
        from crowd.world import props_bytes

        parts["props"] = props_bytes(scene)
    lod = _mode_estimate(scene, characters)
    if lod:
        parts["lod"] = lod
    causes = [(parts["state"] + parts["selection"], f"the state of {n:,} agents: reduce the placements' counts"),
              (parts["characters"], "the characters' meshes and baked clips: fewer triangles or a lower "
                                    "[[characters]] fps"),
              (parts["gpu"] + parts["driver"], f"the GPU buffers of {n:,} agents at {w}x{h}: fewer agents or a "
                                               "smaller [render] size")]
    causes += _mode_causes(scene, characters)
    causes.sort(key=lambda c: -c[0])
    return MemoryEstimate(agents=int(n), parts={k: int(v) for k, v in parts.items()}, causes=causes)


def _mode_causes(scene, characters) -> list:
    """(bytes, clause) per character of the LOD mode's hierarchies when the mode says (its
    ``memory_causes(characters_or_specs, params, names)``), else one clause for them all."""
    try:
        from lod.modes import mode_module

        fn = getattr(mode_module(scene.lod_mode), "memory_causes", None)
    except (ImportError, KeyError):
        fn = None
    if fn is None:
        return []
    chars = characters if characters is not None else list(scene.characters)
    return list(fn(chars, dict(scene.lod_params), [c.name for c in scene.characters]))


def _triangles(spec, character=None) -> int:
    if character is not None:
        if character.kind == "skinned":
            return int(character.mesh.n_triangles)
        return int(max((max((s.indices.shape[0] for s in a.segments), default=0)
                        for a in character.animations.values()), default=0))
    if spec.generator is not None:
        return int(spec.triangles or 5000)
    try:
        return int(os.path.getsize(spec.file) // GLTF_BYTES_PER_TRIANGLE)
    except OSError:
        return 0


def _mode_estimate(scene, characters) -> int:
    """Bytes of the LOD mode's hierarchies: the mode module's ``memory_estimate``
    when it has one, else :data:`LOD_BYTES_PER_TRIANGLE` x triangles."""
    try:
        from lod.modes import mode_module

        fn = getattr(mode_module(scene.lod_mode), "memory_estimate", None)
    except (ImportError, KeyError):
        fn = None
    if fn is not None:
        return int(fn(characters if characters is not None else list(scene.characters), dict(scene.lod_params)))
    per = LOD_BYTES_PER_TRIANGLE.get(scene.lod_mode, 0)
    chars = characters if characters is not None else [None] * len(scene.characters)
    return per * sum(_triangles(sp, ch) for sp, ch in zip(scene.characters, chars))


def available_memory() -> int | None:
    """Bytes the scene may use: ``$CROWD_MEMORY_LIMIT`` if set, else
    ``MemAvailable`` of /proc/meminfo, else physical memory (sysconf), else None."""
    env = os.environ.get(MEMORY_ENV)
    if env:
        try:
            return int(float(env))
        except ValueError:
            pass
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(scene, estimate: MemoryEstimate, available: int | None = None) -> MemoryEstimate:
    """Refuse ``scene`` when ``estimate`` exceeds what the machine has.

    Raises
    ------
    crowd.errors.SceneError
        One sentence with the estimate, the available memory and the agent count.
    """
    avail = available_memory() if available is None else int(available)
    if avail is not None and estimate.total > MEMORY_FRACTION * avail:
        parts = ", ".join(f"{k} {human_bytes(v)}" for k, v in estimate.parts.items())
        causes = getattr(estimate, "causes", None) or [(estimate.total, "reduce the placements' counts or the "
                                                                          "characters' triangles")]
        b, why = causes[0]
        raise SceneError(scene.path, "", f"needs an estimated {human_bytes(estimate.total)} for "
                         f"{estimate.agents:,} agent{'s' if estimate.agents != 1 else ''} ({parts}), "
                         f"more than the {human_bytes(MEMORY_FRACTION * avail)} available; most of it "
                         f"({human_bytes(b)}) is {why}")
    return estimate


def guard(scene, characters=None) -> MemoryEstimate:
    """:func:`estimate_scene` then :func:`check_memory`; returns the estimate."""
    return check_memory(scene, estimate_scene(scene, characters))

