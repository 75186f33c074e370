"""The engine: builds a scene's world and renderer and runs the frame loop.

One frame is: simulate (``World.step``, wall time per system) -> camera at
the simulated time -> LOD select (a DrawList) -> upload / draw / finish on the
renderer (GPU time when the driver has timer queries) -> optional PNG ->
telemetry. The state is checked for NaN/Inf after every step.

Only the effects a scene lists are installed (in the listed order); modules of
other effects are never imported. Everything random derives from the scene
seed, so a run is deterministic for a seed (``CrowdState.digest``).
"""
from __future__ import annotations

import inspect
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from crowd.characters import scene_asset_error
from crowd.errors import SceneError, SimulationError, check_interrupt
from crowd.plan import plan, progress_bar
from crowd.scene import Scene
from lod.debug_colors import COLOR_BY  # noqa: F401  (the fly-through's colour-by modes)
from sim.errors import AssetError as SimAssetError
from sim.params import ParamError

# ---------------------------------------------------------------------------------------------------------------------
# engine
# ---------------------------------------------------------------------------------------------------------------------

#: colourings of the live ``LiveSettings.color_by`` setting (VDR-AM Fig. 11 colours by LOD level)


@dataclass
class LiveSettings:
    """LOD settings that may change while the engine runs (``crowd fly`` live controls).

    Selectors read them as their representations land; the fly-through sets
    them and shows them in its HUD.

    lod_mode : str, a mode of ``crowd.scene.LOD_MODES`` (the scene's ``[lod] mode`` at start)
    splat_size : float, point splat diameter in pixels (point representations), > 0
    poe : float, pixels of error allowed by the LOD cut (VDR-AM §5), > 0
    keyframe_interval : int >= 1, frames between view-dependent selections (Friedrich et al. §4)
    occlusion : bool, occlusion culling on/off (VDR-AM §6)
    freeze : bool, keep the last DrawList's selection while the camera moves (VDR-AM Fig. 9)
    color_by : one of ``COLOR_BY``
    compute_raster : bool, small triangles rasterised in compute (render/raster/; ``[render] raster_threshold``)
    """

    lod_mode: str = "none"
    splat_size: float = 2.0
    poe: float = 1.0
    keyframe_interval: int = 1
    occlusion: bool = False
    freeze: bool = False
    color_by: str = "none"
    compute_raster: bool = True



@dataclass
class RunResult:
    """What a finished run wrote: ``out_dir`` and the summary dict (as in summary.json)."""

    out_dir: Path
    summary: dict
    pngs: list
    digest: str

    def report(self) -> str:
        s = self.summary
        st = s["stages"]
        ms = lambda k: f"{st[k]['mean'] * 1e3:.1f}" if st.get(k) else "-"
        return (f"wrote {self.out_dir}: {s['frames']} frames in {s['wall_seconds']:.2f} s; mean ms per frame: "
                f"total {ms('total')}, simulate {ms('simulate')}, select {ms('select')}, upload {ms('upload')}, "
                f"draw {ms('draw')}, finish {ms('finish')}, gpu {ms('gpu')}; {self.drawn()}; {len(self.pngs)} PNG(s)")

    def drawn(self) -> str:
        """What a frame drew, on average: instances, triangles and, when any, points (a frame drawn only in points
        is not "0 triangles")."""
        c = self.summary.get("counts", {})
        mean = lambda k: float((c.get(k) or {}).get("mean") or 0.0)
        parts = [f"{mean('instances'):,.0f} instances", f"{mean('triangles'):,.0f} triangles"]
        if mean("points") > 0:
            parts.append(f"{mean('points'):,.0f} points")
        return ", ".join(parts) + " per frame"


class Engine:
    """A scene made runnable: world, LOD representations, renderer.

    Parameters
    ----------
    scene : crowd.scene.Scene (validated)
    overrides : dict, optional
        ``frames``, ``size``, ``out``, ``png_every`` (as ``Scene.with_overrides``).
    quiet : bool
        No progress bars.

    Use as a context manager (or call :meth:`close`) so GL objects are released.
    """

    def __init__(self, scene: Scene, overrides: dict | None = None, quiet: bool = False):
        if overrides:
            scene = scene.with_overrides(**overrides)
        self.scene = scene
        self.quiet = quiet
        self.renderer = None
        self.video_options: dict = {}  # crowd.video.VideoWriter keywords of run videos (crowd report: small clips)
        #: which of the frames ``png_every`` selects are written (frame -> bool; None: all of them)
        self.png_frames = None
        #: mode auto: write explain_lod.jsonl (crowd.explain) and pass each frame's text to this callable
        self.explain_lod = None
        self.plan = plan(scene, quiet=quiet)
        self.world = self._build_world()
        from crowd.population import check_journeys

        check_journeys(scene, self.world)  # agents that cannot reach a stage of their journey: refused now
        self.camera_path = self._build_camera()
        try:
            self.reps, self.statics = self._build_reps()
        except SimAssetError as e:  # a character file its representations cannot take: named with scene and key
            raise scene_asset_error(scene.path, scene.characters, e) from None
        self.selector = self._build_selector()
        self.terrain_lod = self._build_terrain_lod()
        from crowd.world import build_scenery

        self.scenery = build_scenery(scene, self.world)  # ground, obstacle solids, props (crowd.world)
        lp = dict(scene.lod_params)
        self.settings = LiveSettings(lod_mode=scene.lod_mode, poe=float(lp.get("poe", LiveSettings.poe)),
                                     splat_size=float(lp.get("splat_size", LiveSettings.splat_size)),
                                     keyframe_interval=self.keyframe_every,
                                     occlusion=bool(lp.get("occlusion", LiveSettings.occlusion)))

    # -- building -----------------------------------------------------------------------------------------------------
    def _build_world(self):
        from sim.world import World

        sc = self.scene
        world = World(state=self.plan.state, characters=self.plan.characters, seed=sc.seed)
        world.resources["character_radius"] = [c.radius for c in sc.characters]  # [[characters]] radius (avoidance)
        if sc.terrain is not None:
            import sim.terrain

            world.resources["terrain"] = sim.terrain.Terrain.from_config(sc.terrain, base_dir=str(sc.path.parent))
        for e in sc.effects:
            try:
                world.install(e.name, e.params)
            except ParamError as err:
                # tables of the effect's own (journeys), or an agent the effect cannot take (routing: outside the area)
                if err.key.split("[", 1)[0] in ("stages", "journeys", "sources", "placement"):
                    raise SceneError(sc.path, err.key, err.message) from None
                raise SceneError(sc.path, f"effects[{e.index}]", err.message if err.key.startswith("effects")
                                 else str(err)) from None
        if getattr(world.state, "tracks", None):  # recorded people: moved by their recordings, after every effect
            import sim.replay.effect

            sim.replay.effect.install(world, {"dt": sc.dt})
            world.effects.append("replay")
        return world

    def _build_camera(self):
        from lod.camera_path import CameraPath

        c = self.scene.camera
        if c.keys:
            return CameraPath([(k.time, k.position, k.target) for k in c.keys])
        return CameraPath([(0.0, c.position, c.target)])

    def camera_at(self, t: float):
        c = self.scene.camera
        return self.camera_path.camera_at(t, fov_y=c.fov, near=c.near, far=c.far)

    def _build_reps(self):
        """Scenery (terrain) as static reps, then the representations and the
        selector of the scene's LOD mode (``lod.modes``)."""
        statics = []
        terrain = self.world.resources.get("terrain")
        if terrain is not None:
            from lod.full.reps import build_static_rep

            statics.append(build_static_rep(terrain.mesh(), key="static:terrain"))
        self.statics = statics
        self._modes = {}  # mode -> (reps, selector), built on first use
        reps, self._selector = self._build_mode(self.scene.lod_mode)
        return reps, statics

    def _build_mode(self, mode: str):
        """(reps, selector) of LOD ``mode``: with the scene's ``[lod]`` keys for
        the scene's own mode, else with the mode's defaults."""
        from lod.modes import mode_module

        built = self._modes.get(mode)
        if built is None:
            sc = self.scene
            params = dict(sc.lod_params) if mode == sc.lod_mode else {}
            progress = False if self.quiet else (lambda it, desc: progress_bar(it, desc, disable=not self.plan.big))
            module = mode_module(mode)
            extra = {}
            if "instancing" in inspect.signature(module.build).parameters:
                # hierarchical instantiation (Wand & Strasser §3.6): the simulation's instancing groups
                extra["instancing"] = self.world.resources.get("instancing")
            if "clips" in inspect.signature(module.build).parameters:
                # build only what the scene can play (point hierarchies of unplayed clips are most of grid's data)
                extra["clips"] = self._played_clips()
            if "variation" in inspect.signature(module.build).parameters:
                # nodes that stand for many agents carry each one's colour variation (lod.points.instancing)
                extra["variation"] = self.tint_table
            built = module.build(
                self.plan.characters, [c.name for c in sc.characters], [c.fps for c in sc.characters],
                params, static_reps=self.statics, progress=progress, **extra)
            reps, selector = built
            self.pose_sharing.register(reps)  # their skinned copies get pose slots (lod.poses)
            built = (reps, self._keyframed(selector, self.keyframe_every))
            self._modes[mode] = built
        return built

    def _played_clips(self) -> list:
        """Per character, the names (in clip order) of the clips its agents can play in this
        run: the clips they start with, plus walk and run of characters whose agents
        the boids gait switches between the two (``sim.boids``); instancing groups'
        clips are added by the mode itself. A character without agents plays none.

        Returns
        -------
        list (one entry per character) of lists of clip names
        """
        st = self.plan.state
        ch = np.asarray(st.character, np.int64)
        cl = np.asarray(st.clip, np.int64)
        gait = getattr(self.world.resources.get("boids"), "clips", None)  # sim.boids' walk/run switch
        from crowd.population import entering_clips

        entering = entering_clips(self.world)  # clips of agents sources add (sim.journeys)
        out = []
        for ci, character in enumerate(self.plan.characters):
            names = character.clip_names()
            played = {int(c) for c in np.unique(cl[ch == ci]) if 0 <= c < len(names)} | entering.get(ci, set())
            if gait is not None:
                played = gait.reachable(ci, played)
            out.append([names[i] for i in sorted(played)])
        return out

    @property
    def pose_sharing(self):
        """The ``lod.poses.PoseSharing`` of the scene's ``[lod] pose_rate``: every frame's skinned copies get
        pose slots, so the renderer skins each distinct pose once (issue 29)."""
        ps = self.__dict__.get("_pose_sharing")
        if ps is None:
            from lod.poses import KEY_RATE, PoseSharing

            ps = self._pose_sharing = PoseSharing(dict(self.scene.lod_common).get("pose_rate", KEY_RATE))
        return ps

    @property
    def keyframe_every(self) -> int:
        """``[lod] keyframe_every`` of the scene (1 = per-frame selection)."""
        return int(dict(self.scene.lod_common).get("keyframe_every", 1))

    def _keyframed(self, selector, n: int):
        """``selector`` wrapped in a :class:`lod.temporal.selection.KeyframedSelector`
        when ``n > 1`` (Friedrich et al. §3 for the crowd's LOD), else itself."""
        if int(n) <= 1:
            return selector
        from lod.temporal.selection import KEYFRAME_EXTRAPOLATION_DEFAULT, KeyframedSelector

        if hasattr(selector, "switch_frames"):  # mode auto: the keyframe blend fades its plan switches
            selector.switch_frames = 0
        if getattr(selector, "far", None) is not None:  # the blend re-packs every agent as its keyframe lists
            selector.far = None  # drew it: a far splat's row is not an instance row (lod.far; not blended yet)
        common = dict(self.scene.lod_common)
        mode = common.get("keyframe_extrapolation", KEYFRAME_EXTRAPOLATION_DEFAULT)
        return KeyframedSelector(selector, int(n), mode, geomorph=bool(common.get("keyframe_geomorph", True)))

    def _build_terrain_lod(self, lod: str | None = None):
        """The view-dependent bisection terrain (Friedrich et al.), when the
        scene's [terrain] asks for ``lod = "bisection"`` (or ``lod`` does); else None (the
        full-resolution terrain mesh is drawn as a static rep)."""
        terrain = self.world.resources.get("terrain")
        if terrain is None:
            return None
        from lod.temporal.terrain_keyframes import terrain_lod_from_params

        params = dict(self.scene.terrain_lod)
        if lod is not None:
            params["lod"] = lod
        return terrain_lod_from_params(terrain, self.scene.render.size, params, self.scene.dt)

    def set_terrain_lod(self, on: bool) -> bool:
        """Draw a full-resolution terrain view-dependently (``on``: the bisection hierarchy at the scene's
        ``lod_tau``, as ``[terrain] lod = "bisection"`` would) or as the scene wrote it (the fly-through's
        budget: mode auto covers the ground too). A scene whose terrain is already view-dependent, or without
        a terrain, is left as it is. Returns whether the terrain is drawn view-dependently now."""
        if self.world.resources.get("terrain") is None or dict(self.scene.terrain_lod).get("lod") == "bisection":
            return self.terrain_lod is not None
        if on and self.terrain_lod is None:
            self.terrain_lod = self._build_terrain_lod("bisection")
        elif not on and self.terrain_lod is not None:
            self.terrain_lod = None
            if self.renderer is not None:  # the full-resolution mesh back in place of the last selected one
                for rep in self.statics:
                    if rep.key == "static:terrain":
                        self.renderer.upload(rep)
        return self.terrain_lod is not None

    def terrain_frame(self, camera, renderer) -> tuple:
        """Select (or interpolate) this frame's terrain and upload it in place of
        the full-resolution terrain; returns (camera to draw with, metrics dict).

        In "delayed" extrapolation mode the frame is drawn with the delayed
        camera (Friedrich et al. §4.1, mode 1)."""
        if self.terrain_lod is None:
            return camera, {}
        from lod.full.reps import build_static_rep

        fr = self.terrain_lod.frame(camera)
        renderer.upload(build_static_rep(fr.mesh(), key="static:terrain"))
        metrics = {"terrain_triangles": float(len(fr.triangles)), "terrain_selected": float(bool(fr.selected)),
                   "err_inter": fr.err_inter, "err_view": fr.err_view, "err_extra": fr.err_extra,
                   "terrain_delay": fr.delay}
        return (fr.camera if fr.camera is not None else camera), metrics

    def set_lod_mode(self, mode: str) -> None:
        """Switch the LOD mode while running (the fly-through's live control).

        The mode's representations are built once (hierarchies come from the
        disk cache when present) and uploaded to the open renderer.
        """
        self.prepare_mode(mode)
        self.reps, self.selector = self._modes[mode]
        self.settings.lod_mode = mode

    def prepare_mode(self, mode: str):
        """The selector of LOD ``mode``, its representations built once (hierarchies from the disk cache when
        present) and uploaded to the open renderer, without switching to it (the fly-through's budget keeps
        mode auto ready beside the scene's mode)."""
        if mode not in self.lod_modes:
            raise ValueError(f"lod mode {mode!r}: expected one of {', '.join(self.lod_modes)}")
        fresh = mode not in self._modes
        reps, selector = self._build_mode(mode)
        if fresh and self.renderer is not None:
            for rep in reps:
                self.renderer.upload(rep)
        return selector

    def warm_up(self, mode: str, camera, size) -> int:
        """Draw each representation of the prepared ``mode`` once, coarse, into the open renderer (the image is
        drawn over by the next frame): the first frame that draws one of them then costs what later ones do
        (:meth:`lod.auto.delegate.Delegates.warm_lists`; mode auto only). Returns the lists drawn."""
        built = self._modes.get(mode)
        sel = getattr(built[1], "inner", built[1]) if built is not None else None
        delegates = getattr(sel, "delegates", None)
        if delegates is None or self.renderer is None:
            return 0
        statics = [(r.key, np.eye(4)) for r in self.statics]
        lists = delegates.warm_lists(self.drawn_state(), camera, size, statics, sel.candidates)
        for dl in lists:
            self.pose_sharing.assign(dl)
            self.renderer.draw(dl, self.scene.render.background)
        return len(lists)

    def _build_selector(self):
        return self._selector

    def _open_renderer(self):
        if self.renderer is None:
            from render.renderer import Renderer

            self.renderer = self._lit(Renderer(self.scene.render.size))
            self.renderer.tint_table = self.tint_table
            for rep in [*self.reps, *self.statics, *self.scenery.reps]:
                self.renderer.upload(rep)
        return self.renderer

    def _lit(self, renderer):
        """``renderer`` with the scene's light and shadows (``[render] light_*``, ``shadows``; render.shadows)."""
        r = self.scene.render
        renderer.lighting.configure(r.light, r.shadows, r.shadow_distance, r.shadow_map_size)
        renderer.raster_threshold = r.raster_threshold  # the compute rasteriser (render/raster/)
        renderer.compute_raster = renderer.compute_raster and self.settings.compute_raster
        return renderer

    @property
    def lod_modes(self) -> tuple:
        """LOD modes this engine can select (``crowd.scene.LOD_MODES``)."""
        from crowd.scene import LOD_MODES

        return tuple(LOD_MODES)

    def open_renderer(self, size=None, ctx=None):
        """(Re)create the renderer at ``size`` (default: the scene's) on ``ctx``
        (default: a headless EGL context), uploading every representation.

        Used by the fly-through (a glfw window's context; again after a resize).
        The previous renderer, if any, is released first.
        """
        from render.renderer import Renderer

        self.close()
        self.renderer = self._lit(Renderer(tuple(size) if size is not None else self.scene.render.size, ctx=ctx))
        self.renderer.tint_table = self.tint_table
        for reps, _ in self._modes.values():
            for rep in reps:
                self.renderer.upload(rep)
        for rep in [*self.statics, *self.scenery.reps]:
            self.renderer.upload(rep)
        return self.renderer

    @property
    def tint_table(self):
        """(n agents,) uint32 colour-variation words (``lod.variation.variation_table``: from the scene
        seed and each agent's stable id and character), or None when no character varies."""
        if not hasattr(self, "_tint_table"):
            from lod.variation import variation_table

            vs = [dict(c.variation) if c.variation else None for c in self.scene.characters]
            st = self.world.state
            self._tint_table = variation_table(self.scene.seed, st.character, vs, ids=st.ids) if any(vs) else None
        return self._tint_table

    @property
    def static_keys(self) -> frozenset:
        """Representation keys of the scenery (terrain), never tinted by colour-by."""
        return frozenset(r.key for r in self.statics) | self.scenery.keys

    def drawn_state(self):
        """The state as drawn: the world's, with replayed people's planted-feet offsets added to their positions
        (``sim.replay.planting``; the world's state keeps the recorded positions that trajectories and measures
        read)."""
        plant = self.world.resources.get("replay_feet")
        return self.world.state if plant is None else plant.drawn(self.world.state)

    def select(self, camera, size):
        """The DrawList of the current state seen by ``camera`` at ``size`` (the
        selection ``run`` makes each frame, statics included)."""
        static_draws = [(r.key, np.eye(4)) for r in self.statics]
        self.apply_live_settings()
        dl = self.selector.select(self.drawn_state(), camera, size, statics=static_draws)
        self.pose_sharing.assign(dl)
        return self.scenery.add(dl, camera, size, self.settings.poe, self.settings.lod_mode)

    def observe(self, drawlist, select_seconds: float, timings: dict) -> float:
        """The cost of a frame drawn that a budget covers -- LOD selection and rendering (``timings``' upload,
        draw, finish: :meth:`render.renderer.Renderer.draw`); the simulation is the scene's own cost -- reported
        to a selector that adapts to it (mode auto fits its costs and moves its budget's bound by the frames it
        drew: :meth:`lod.auto.mode.AutoSelector.observe`). ``crowd run`` and ``crowd fly`` both report every
        frame. Returns those seconds."""
        measured = float(select_seconds) + sum(float(timings.get(k) or 0.0) for k in ("upload", "draw", "finish"))
        if hasattr(self.selector, "observe"):
            self.selector.observe(measured, select_seconds=float(select_seconds), drawlist=drawlist)
        return measured

    def apply_live_settings(self) -> None:
        """Hand the live LOD settings to the current selector: pixels of error
        to a cluster cut, the splat size to a point traversal (the drawer
        splats at the size the DrawList names), the keyframe interval to the
        keyframed selection (wrapping the mode's selector when it becomes > 1;
        restarting its keyframes when it changes) and the occlusion toggle to
        the cluster representations (and the open renderer's cluster drawer)."""
        from lod.temporal.selection import KeyframedSelector

        s = self.settings
        n = max(1, int(s.keyframe_interval))
        if isinstance(self.selector, KeyframedSelector):
            if self.selector.n != n:
                self.selector.set_interval(n)
        elif n > 1:
            self.selector = self._keyframed(self.selector, n)
            mode = s.lod_mode if s.lod_mode in self._modes else self.scene.lod_mode
            if mode in self._modes:
                self._modes[mode] = (self._modes[mode][0], self.selector)
        self.apply_occlusion(bool(s.occlusion))
        sel = self.selector
        if hasattr(sel, "poe"):
            sel.poe = float(s.poe)
        if hasattr(sel, "splat_size"):
            sel.splat_size = int(min(3, max(1, round(s.splat_size))))

    def apply_occlusion(self, on: bool) -> None:
        """Occlusion culling (VDR-AM §5.2) of the cluster representations on or off:
        sets ``occlusion`` on the LOD reps and on the open renderer's per-rep state;
        and of the point-hierarchy nodes (``render.points.occlusion``) on the points drawer."""
        for reps, _ in self._modes.values():
            for rep in reps:
                if hasattr(rep, "occlusion") and getattr(rep, "kind", "") == "clusters":
                    rep.occlusion = bool(on)
        d = self.renderer.uploaded_drawer("clusters") if self.renderer is not None else None
        if d is not None:  # render.clusters.draw keeps its own state per uploaded rep
            d.set_occlusion(bool(on))
        d = self.renderer.uploaded_drawer("points") if self.renderer is not None else None
        if d is not None:
            d.occlusion = bool(on)

    def close(self) -> None:
        if self.renderer is not None:
            self.renderer.release()
            self.renderer = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- running ------------------------------------------------------------------------------------------------------
    def step(self, timings: dict | None = None) -> None:
        """One simulation frame; raises SimulationError when the state stops being finite."""
        sc = self.scene
        self.world.step(sc.dt, sc.substeps, timings)
        if self.world.agents_changed is not None:  # agents left or entered (sim.population)
            from crowd.population import after_step

            after_step(self)
        try:
            self.world.state.check_finite()
        except FloatingPointError as e:
            raise SimulationError(f"{sc.path}: frame {self.world.frame}: {e} after the step "
                                  f"(effects: {', '.join(sc.effect_names) or 'none'}); nothing was written") from None

    def _trajectory_writer(self, tmp: Path):
        """A :class:`crowd.trajectories.TrajectoryWriter` of ``tmp/trajectories.txt`` when the scene asks for
        trajectories (``[output] trajectories``), else a null context yielding None."""
        from contextlib import nullcontext

        if not getattr(self.scene, "trajectories", False):
            return nullcontext(None)
        from crowd.population import changing_count
        from crowd.trajectories import TRAJECTORY_FILE, TrajectoryWriter

        sc = self.scene
        return TrajectoryWriter(tmp / TRAJECTORY_FILE, sc.name, self.world.state.n, sc.dt, sc.substeps,
                                changing=changing_count(self.world))

    def _explain_writer(self, tmp: Path):
        """A :class:`crowd.explain.ExplainWriter` of ``tmp/explain_lod.jsonl`` when ``explain_lod`` is set (the
        selector then adds its per-group counts and fit to ``stats["auto"]``), else a null context."""
        from contextlib import nullcontext

        if not self.explain_lod:
            return nullcontext(None)
        from crowd.explain import EXPLAIN_FILE, ExplainWriter

        if hasattr(self.selector, "explain"):
            self.selector.explain = True
        return ExplainWriter(tmp / EXPLAIN_FILE)

    def run(self, frames: int | None = None, out_dir: str | Path | None = None,
            png_every: int | None = None) -> RunResult:
        """Run ``frames`` frames, writing telemetry (and PNGs) atomically to ``out_dir``.

        Defaults come from the scene. The output directory appears only when
        the run has finished; on error or interrupt nothing is left behind.
        """
        from crowd.output import atomic_dir, check_output_dir
        from crowd.telemetry import FrameRecord, Telemetry, machine_info

        sc = self.scene
        frames = sc.frames if frames is None else int(frames)
        out_dir = check_output_dir(out_dir if out_dir is not None else sc.output_dir)
        png_every = sc.render.png_every if png_every is None else int(png_every)
        size = sc.render.size
        bg = sc.render.background
        renderer = self._open_renderer()
        tel = Telemetry(systems=[s.name for s in self.world.schedule.order()])
        pngs = []
        static_draws = [(r.key, np.eye(4)) for r in self.statics]
        from crowd.images import write_png
        from crowd.population import frame_counts, summary as population_summary
        from crowd.video import VIDEO_NAME, video_writer

        agents_start = self.world.state.n
        with atomic_dir(out_dir) as tmp, self._trajectory_writer(tmp) as traj, self._explain_writer(tmp) as explain, \
                video_writer(tmp / VIDEO_NAME, size, 1.0 / sc.dt, sc.video, **self.video_options) as video:
            if png_every:
                (tmp / "frames").mkdir()
            run_start = time.perf_counter()
            for f in progress_bar(range(frames), sc.name, disable=self.quiet, total=frames):
                check_interrupt()  # an interrupt another library swallowed stops the run here (crowd.errors)
                t_frame = time.perf_counter()
                stages, systems = {}, {}
                self.step(systems)
                t1 = time.perf_counter()
                stages["simulate"] = (0.0, t1 - t_frame)
                camera = self.camera_at(self.world.time)
                camera, metrics = self.terrain_frame(camera, renderer)
                dl = self.selector.select(self.drawn_state(), camera, size, statics=static_draws)
                self.pose_sharing.assign(dl)  # pose slots of the skinned copies (lod.poses)
                self.scenery.add(dl, camera, size, self.settings.poe, self.settings.lod_mode)
                t2 = time.perf_counter()
                stages["select"] = (t1 - t_frame, t2 - t1)
                if "keyframe" in dl.stats:  # keyframed selection (lod.temporal.selection)
                    metrics = {**metrics, "lod_keyframe": float(bool(dl.stats["keyframe"])),
                               "lod_selection_ms": 1e3 * float(getattr(self.selector, "last_selection_seconds", 0.0)),
                               "lod_transitions": float(dl.stats.get("transitions", 0)),
                               "lod_geomorphs": float(dl.stats.get("geomorphs", 0))}
                r = renderer.draw(dl, bg)
                measured = self.observe(dl, t2 - t1, r)
                if explain is not None and isinstance(dl.stats.get("auto"), dict):
                    text = explain.frame(f, dl.stats["auto"], measured - (t2 - t1), dl.warm_up)
                    if callable(self.explain_lod):
                        self.explain_lod(text)
                auto = dl.stats.get("auto")
                if isinstance(auto, dict) and auto.get("predicted_ms") is not None:
                    metrics = {**metrics, "predicted_ms": float(auto["predicted_ms"]),
                               "measured_ms": 1e3 * measured, "lod_bound": float(auto.get("bound") or 0.0),
                               # predicted_ms prices the rendering: compare it with this, not with measured_ms
                               "measured_render_ms": 1e3 * (measured - (t2 - t1))}
                if dl.poses is not None:  # pose sharing (lod.poses, render.poses.cache): what it skinned, and in what time
                    metrics = {**metrics, "poses": float(dl.stats.get("poses", 0)),
                               "posed_vertices": float(dl.stats.get("posed_vertices", 0)),
                               "pose_ms": 1e3 * float(r.get("poses") or 0.0)}
                off = t2 - t_frame
                for s in ("upload", "draw", "finish"):
                    d = float(r.get(s) or 0.0)
                    stages[s] = (off, d)
                    off += d
                t_png = time.perf_counter()
                if png_every and f % png_every == 0 and (self.png_frames is None or self.png_frames(f)):
                    p = tmp / "frames" / f"frame_{f:05d}.png"
                    write_png(p, renderer.read_pixels())
                    pngs.append(out_dir / "frames" / p.name)
                if traj is not None:  # streamed: one frame in memory (crowd.trajectories)
                    traj.write(f, self.world.state.position, self.world.state.ids)
                if video is not None and video.accepting:  # every frame (crowd.video), timed as the png stage
                    video.write(renderer.read_pixels())
                t_end = time.perf_counter()
                # output writes: PNG read-back + encode (0 on frames without one), trajectory lines
                stages["png"] = (t_png - t_frame, t_end - t_png)
                counts = {"instances": dl.stats.get("instances", dl.n_instances),
                          "culled": dl.stats.get("culled", 0),
                          "triangles": dl.stats.get("triangles", dl.triangles),
                          "points": dl.stats.get("points", dl.points),
                          "batches": len(dl.batches), "props": dl.stats.get("props", 0),
                          "raster_triangles": dl.stats.get("raster_triangles", 0),
                          "pose_passes": dl.stats.get("pose_passes", 0), **frame_counts(self.world)}
                tel.add(FrameRecord(frame=f, sim_time=self.world.time, start=t_frame - run_start,
                                    total=t_end - t_frame, stages=stages, gpu=r.get("gpu"), systems=systems,
                                    counts=counts, samples_passed=r.get("samples_passed"), metrics=metrics))
            digest = self.world.state.digest()
            extra = {"size": list(size), "dt": sc.dt, "substeps": sc.substeps, "seed": sc.seed,
                     "agents": agents_start, "effects": sc.effect_names, "lod_mode": sc.lod_mode,
                     "scene_file": str(sc.path), "state_digest": digest, "pngs": len(pngs),
                     "trajectories": traj.path.name if traj is not None else None,
                     "video": VIDEO_NAME if video is not None else None, "shadows": sc.render.shadows,
                     **population_summary(self.world)}
            from render.context import gl_info

            summary = tel.write(tmp, sc.name, extra, machine_info(gl_info(renderer.ctx)))
        return RunResult(out_dir=out_dir, summary=summary, pngs=pngs, digest=digest)
