"""``crowd fly``: an interactive fly-through of a running scene in a glfw window.

The engine simulates and renders exactly as in ``crowd run`` (``Engine.step``,
``Engine.select``, ``Renderer.draw``); the window only supplies the camera,
live settings, and shows the renderer's frame with a HUD on top.

Controls (also printed by H / F1)::

    W A S D        move forward / left / back / right (along the view), Q / E down / up (world Y)
    mouse drag     look around: hold the left or right button and move (the cursor is not captured)
    scroll         movement speed x1.25 per notch
    space          pause / resume the simulation;  N  one step while paused
    M              cycle the LOD mode (none, points, triangles, clusters, auto; unavailable modes say so)
    [ ]            splat size -/+         - =   pixels of error (PoE) /2 x2
    , .            keyframe interval -/+  O     occlusion culling on/off
    F              freeze the LOD selection (VDR-AM Fig. 9: look at a frozen cut from outside)
    C              colour by: none / representation / level (VDR-AM Fig. 11)
    K              compute rasteriser of small triangles on/off (render/raster/)
    R              start / stop recording the camera path (JSON, replayable as [camera] path_file)
    P or F12       screenshot (PNG of the rendered frame, without HUD)
    Tab            HUD on/off        H or F1   help        Esc   quit

The controller (:class:`FlyController`) holds the camera, settings and key
state; its plain methods ``on_key``, ``on_mouse_button``, ``on_mouse_move``,
``on_scroll``, ``on_resize`` and ``on_focus`` are what glfw's callbacks call (via
``render.window.Window.attach``), and tests call them too.

Recorded camera paths are keyed on the *frame clock*: the k-th recorded frame
(k = 0, 1, ...) gets time ``(k + 1) * dt`` (the scene's fixed step). ``crowd
run`` evaluates the camera at the simulated time after each frame's step, i.e.
``(f + 1) * dt`` at frame f, so frame f of a replay shows the pose of the f-th
recorded frame, whatever the interactive frame rate was.
"""
from __future__ import annotations

import math
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from crowd.engine import COLOR_BY
from crowd.errors import check_interrupt
from lod.debug_colors import apply_tints

#: default movement speed, metres per second
FLY_SPEED = 5.0
#: allowed movement speeds, metres per second
FLY_SPEED_RANGE = (0.05, 2000.0)
#: speed factor per scroll notch
FLY_SCROLL_FACTOR = 1.25
#: radians of yaw / pitch per pixel of mouse movement
FLY_SENSITIVITY = 0.004
#: pitch is kept within +- this (radians), so the view never flips over the pole
FLY_PITCH_LIMIT = math.radians(89.0)
#: longest frame step used for movement, seconds (a stall does not teleport the camera)
FLY_MAX_DT = 0.25
#: seconds a HUD message stays visible
MESSAGE_SECONDS = 4.0
#: every LOD mode the fly-through can cycle through (the engine says which exist)
LOD_MODES_ALL = ("none", "points", "triangles", "clusters", "auto")
#: splat size range and step, pixels
SPLAT_RANGE, SPLAT_STEP = (1.0, 3.0), 1.0  # the point splats' sizes (lod.points.mode)
#: pixels-of-error range (halved / doubled per key)
POE_RANGE = (0.125, 64.0)
#: keyframe interval range, frames
KEYFRAME_RANGE = (1, 64)
#: seconds between HUD text refreshes (numbers readable, text not re-rasterised every frame);
#: any input refreshes it at once
HUD_REFRESH = 0.1
#: frames the HUD's rate is measured over: frames drawn divided by the wall-clock time between their starts
RATE_FRAMES = 20
#: exit code when no display is available (as for bad usage)
EXIT_NO_DISPLAY = 2

HELP_TEXT = """\
W A S D: move (along the view)   Q / E: down / up   mouse drag (left/right button): look   scroll: speed
space: pause   N: step while paused   M: LOD mode   [ ]: splat size   - =: PoE   , .: keyframe interval
9 / 0: frame budget down / up (mode auto draws under it)
O: occlusion culling   F: freeze LOD selection   C: colour by rep/level   K: compute raster
R: record camera path
P / F12: screenshot   Tab: HUD   H / F1: help   Esc: quit"""


def no_display_message(scene: str = "SCENE", reason: str = "DISPLAY/WAYLAND_DISPLAY unset") -> str:
    """The one sentence printed when no window can be opened."""
    return (f"crowd fly: no display to open a window on ({reason}); "
            f"render headless with `crowd run {scene}` or run under Xvfb: `xvfb-run crowd fly {scene}`")


def reframe(drawlist, camera, size):
    """The same selection (batches, instance ids, animation data) seen from ``camera``.

    A DrawList's positions are relative to its ``origin`` (the camera position
    when it was selected); this shifts every instance's translation to the new
    camera position (in float64) and replaces the view and projection. Used to
    freeze the LOD selection while the camera moves.

    Parameters
    ----------
    drawlist : lod.drawlist.DrawList (not modified)
    camera : lod.view.Camera
    size : (width, height) pixels

    Returns
    -------
    lod.drawlist.DrawList
    """
    import dataclasses

    from lod.drawlist import DrawList

    w, h = int(size[0]), int(size[1])
    origin = np.asarray(camera.position, np.float64).copy()
    shift = np.asarray(drawlist.origin, np.float64) - origin
    batches = []
    for b in drawlist.batches:
        d = np.array(b.instance_data, np.float32, copy=True)
        if d.shape[0]:
            t = d[:, [3, 7, 11]].astype(np.float64) + shift
            d[:, [3, 7, 11]] = t.astype(np.float32)
        # replace() keeps what a mode's batch subclass adds (cluster cuts, point jobs, index ranges)
        batches.append(dataclasses.replace(b, instance_data=d))
    return DrawList(origin=origin, view=camera.view_matrix().astype(np.float32),
                    proj=camera.projection(w / max(1, h)).astype(np.float32), size=(w, h), batches=batches,
                    stats=dict(drawlist.stats), options=dict(drawlist.options))


def _stamp() -> str:
    t = time.time()
    return time.strftime("%Y%m%d-%H%M%S", time.localtime(t)) + f"-{int(t * 1000) % 1000:03d}"


def _free_path(folder: Path, stem: str, suffix: str) -> Path:
    p = folder / f"{stem}{suffix}"
    i = 1
    while p.exists():
        p = folder / f"{stem}-{i}{suffix}"
        i += 1
    return p


# ---------------------------------------------------------------------------------------------------------------------
# controller: camera, settings, input (no GL)
# ---------------------------------------------------------------------------------------------------------------------


class FlyController:
    """Free camera, live settings and recording state, driven by plain input methods.

    Parameters
    ----------
    engine : crowd.engine.Engine (its ``settings`` are changed in place)
    camera : lod.view.Camera, the starting pose (fov/near/far are kept)
    size : (width, height) framebuffer pixels
    out_dir : Path where screenshots and recordings go
    record_path : Path of the recording, or None for a timestamped file in ``out_dir``
    echo : callable printing a line to the user (default: print to stdout)

    Attributes
    ----------
    position : (3,) float64 ; yaw, pitch : float radians (``lod.view.Camera.from_yaw_pitch``)
    speed : float m/s ; sensitivity : float rad/pixel
    paused, hud_visible, help_visible, dragging : bool
    pending_size : (w, h) or None, a resize not yet applied
    recording : bool ; recorded : list of (time, position, target) keys
    """

    def __init__(self, engine, camera, size, out_dir, record_path=None, echo=print):
        import glfw

        self._glfw = glfw
        self.engine = engine
        self.settings = engine.settings
        self.position = np.asarray(camera.position, np.float64).copy()
        self.yaw = float(camera.yaw)
        self.pitch = float(np.clip(camera.pitch, -FLY_PITCH_LIMIT, FLY_PITCH_LIMIT))
        self.fov_y, self.near, self.far = float(camera.fov_y), float(camera.near), float(camera.far)
        self.speed = FLY_SPEED
        self.sensitivity = FLY_SENSITIVITY
        self.size = (int(size[0]), int(size[1]))
        self.pending_size = None
        self.out_dir = Path(out_dir)
        self.record_path = Path(record_path) if record_path is not None else None
        self.echo = echo
        self.held: set = set()
        self.dragging = False
        self._cursor = None
        self.paused = False
        self.step_once = False
        self.hud_visible = True
        self.help_visible = False
        self.screenshot_requested = False
        self.quit_requested = False
        self.recording = False
        self.recorded: list = []
        self.saved_paths: list = []
        self.messages: list = []  # (text, expiry on the controller clock)
        self.clock = 0.0
        self.revision = 0  # counts input events that may change what the HUD shows
        self.budget = None  # crowd.fly_budget.FlyBudget, set by FlyApp
        self._mode_cursor = LOD_MODES_ALL.index(self.settings.lod_mode) if self.settings.lod_mode in LOD_MODES_ALL else 0
        k = glfw
        self._move_keys = {k.KEY_W: (0, 1), k.KEY_S: (0, -1), k.KEY_D: (1, 1), k.KEY_A: (1, -1),
                           k.KEY_E: (2, 1), k.KEY_Q: (2, -1)}
        self._press = {
            k.KEY_SPACE: self.toggle_pause, k.KEY_N: self.request_step, k.KEY_M: self.cycle_mode,
            k.KEY_O: self.toggle_occlusion, k.KEY_F: self.toggle_freeze, k.KEY_C: self.cycle_color,
            k.KEY_K: self.toggle_compute_raster,
            k.KEY_R: self.toggle_recording, k.KEY_P: self.request_screenshot, k.KEY_F12: self.request_screenshot,
            k.KEY_9: lambda: self.budget.change(-1) if self.budget is not None else None,
            k.KEY_0: lambda: self.budget.change(1) if self.budget is not None else None,
            k.KEY_H: self.show_help, k.KEY_F1: self.show_help, k.KEY_TAB: self.toggle_hud,
            k.KEY_ESCAPE: self.request_quit,
        }
        self._repeat = {
            k.KEY_LEFT_BRACKET: lambda: self.adjust("splat_size", -1), k.KEY_RIGHT_BRACKET: lambda: self.adjust("splat_size", 1),
            k.KEY_MINUS: lambda: self.adjust("poe", -1), k.KEY_EQUAL: lambda: self.adjust("poe", 1),
            k.KEY_COMMA: lambda: self.adjust("keyframe_interval", -1),
            k.KEY_PERIOD: lambda: self.adjust("keyframe_interval", 1),
        }

    # -- camera --------------------------------------------------------------------------------------------------------
    def camera(self):
        """The current lod.view.Camera."""
        from lod.view import Camera

        return Camera.from_yaw_pitch(self.position, self.yaw, self.pitch, fov_y=self.fov_y, near=self.near,
                                     far=self.far)

    def axes(self) -> tuple:
        """(forward, right, up) unit (3,) float64 vectors of the movement keys."""
        cam = self.camera()
        return cam.forward, cam.rotation[:, 0].copy(), np.array([0.0, 1.0, 0.0])

    def update(self, dt: float) -> None:
        """Advance the controller clock by ``dt`` seconds and move by the held keys:
        each held key moves ``speed * dt`` metres along its axis (forward / right / world up)."""
        dt = float(min(max(dt, 0.0), FLY_MAX_DT))
        self.clock += dt
        self.messages = [(m, t) for m, t in self.messages if t > self.clock]
        if not self.held:
            return
        axes = self.axes()
        move = np.zeros(3)
        for key in self.held:
            axis, sign = self._move_keys[key]
            move += sign * axes[axis]
        self.position = self.position + move * (self.speed * dt)

    def look(self, dx: float, dy: float) -> None:
        """Turn by a mouse movement of (dx, dy) pixels: yaw decreases by ``sensitivity * dx``
        (moving right turns right), pitch decreases by ``sensitivity * dy`` (moving up looks up)."""
        self.yaw = (self.yaw - self.sensitivity * dx + math.pi) % (2 * math.pi) - math.pi
        self.pitch = float(np.clip(self.pitch - self.sensitivity * dy, -FLY_PITCH_LIMIT, FLY_PITCH_LIMIT))

    # -- input (called by glfw callbacks and tests) --------------------------------------------------------------------
    def on_key(self, key: int, action: int, mods: int = 0) -> None:
        glfw = self._glfw
        self.revision += 1
        if key in self._move_keys:
            if action == glfw.PRESS:
                self.held.add(key)
            elif action == glfw.RELEASE:
                self.held.discard(key)
            return
        if action == glfw.PRESS and key in self._press:
            self._press[key]()
        elif action in (glfw.PRESS, glfw.REPEAT) and key in self._repeat:
            self._repeat[key]()

    def on_mouse_button(self, button: int, action: int, mods: int = 0) -> None:
        glfw = self._glfw
        if button in (glfw.MOUSE_BUTTON_LEFT, glfw.MOUSE_BUTTON_RIGHT):
            self.dragging = action == glfw.PRESS
            self._cursor = None

    def on_mouse_move(self, x: float, y: float) -> None:
        if self.dragging and self._cursor is not None:
            self.look(x - self._cursor[0], y - self._cursor[1])
        self._cursor = (float(x), float(y))

    def on_scroll(self, dx: float, dy: float) -> None:
        self.revision += 1
        self.speed = float(np.clip(self.speed * FLY_SCROLL_FACTOR ** float(dy), *FLY_SPEED_RANGE))

    def on_focus(self, focused: bool) -> None:
        """Losing the focus releases held keys and the mouse drag (their release events go elsewhere)."""
        if not focused:
            self.held.clear()
            self.dragging = False
            self._cursor = None

    def on_resize(self, width: int, height: int) -> None:
        """Remember a new framebuffer size; the app applies it before the next frame
        (a minimised window, 0 x 0, is ignored)."""
        if width > 0 and height > 0:
            self.pending_size = (int(width), int(height))
            self.revision += 1

    # -- actions -------------------------------------------------------------------------------------------------------
    def say(self, text: str, seconds: float = MESSAGE_SECONDS, echo: bool = True) -> None:
        """Show ``text`` in the HUD for ``seconds`` (and print it)."""
        self.revision += 1
        self.messages.append((text, self.clock + seconds))
        del self.messages[:-4]
        if echo and self.echo is not None:
            self.echo(text)

    def toggle_pause(self) -> None:
        self.paused = not self.paused
        self.say("simulation paused" if self.paused else "simulation running", echo=False)

    def request_step(self) -> None:
        if self.paused:
            self.step_once = True

    def cycle_mode(self) -> None:
        """Next mode of :data:`LOD_MODES_ALL`; only modes the engine has are set."""
        cur = self.settings.lod_mode  # the mode drawn (the budget may have switched it to auto)
        i = LOD_MODES_ALL.index(cur) if cur in LOD_MODES_ALL else self._mode_cursor
        self._mode_cursor = (i + 1) % len(LOD_MODES_ALL)
        mode = LOD_MODES_ALL[self._mode_cursor]
        if mode in self.engine.lod_modes:
            self.engine.set_lod_mode(mode)
            if self.budget is not None:
                self.budget.mode_picked()
            self.say(f"lod mode {mode}")
        else:
            self.say(f"mode {mode} not available yet")

    def adjust(self, name: str, direction: int) -> None:
        s = self.settings
        if name == "splat_size":
            s.splat_size = float(np.clip(s.splat_size + direction * SPLAT_STEP, *SPLAT_RANGE))
            self.say(f"splat size {s.splat_size:g} px", echo=False)
        elif name == "poe":
            s.poe = float(np.clip(s.poe * (2.0 ** direction), *POE_RANGE))
            self.say(f"pixels of error {s.poe:g}", echo=False)
        elif name == "keyframe_interval":
            s.keyframe_interval = int(np.clip(s.keyframe_interval + direction, *KEYFRAME_RANGE))
            self.say(f"keyframe interval {s.keyframe_interval}", echo=False)
        else:
            raise KeyError(f"FlyController.adjust: unknown setting {name!r}")

    def toggle_occlusion(self) -> None:
        self.settings.occlusion = not self.settings.occlusion
        self.say(f"occlusion culling {'on' if self.settings.occlusion else 'off'}", echo=False)

    def toggle_compute_raster(self) -> None:
        """Small triangles to the compute rasteriser (render/raster/) or all to the hardware path."""
        s = self.settings
        s.compute_raster = not s.compute_raster
        r = getattr(self.engine, "renderer", None)
        if r is not None:
            r.compute_raster = s.compute_raster and int(getattr(r.ctx, "version_code", 0)) >= 430
        self.say(f"compute raster {'on' if s.compute_raster else 'off'}", echo=False)

    def toggle_freeze(self) -> None:
        self.settings.freeze = not self.settings.freeze
        self.say("LOD selection frozen" if self.settings.freeze else "LOD selection live", echo=False)

    def cycle_color(self) -> None:
        s = self.settings
        s.color_by = COLOR_BY[(COLOR_BY.index(s.color_by) + 1) % len(COLOR_BY)] if s.color_by in COLOR_BY else "none"
        self.say(f"colour by {s.color_by}", echo=False)

    def request_screenshot(self) -> None:
        self.screenshot_requested = True

    def request_quit(self) -> None:
        self.quit_requested = True

    def toggle_hud(self) -> None:
        self.hud_visible = not self.hud_visible

    def show_help(self) -> None:
        self.help_visible = not self.help_visible
        if self.echo is not None:
            self.echo(HELP_TEXT)

    # -- recording -----------------------------------------------------------------------------------------------------
    def toggle_recording(self) -> None:
        if self.recording:
            self.stop_recording()
        else:
            self.recording = True
            self.recorded = []
            self.say("recording the camera path (R stops)")

    def record(self, camera) -> None:
        """Add this frame's pose (k-th recorded frame at time (k + 1) * dt, see the module notes)."""
        if not self.recording:
            return
        t = (len(self.recorded) + 1) * float(self.engine.scene.dt)
        p = np.asarray(camera.position, np.float64)
        self.recorded.append((t, p.copy(), p + camera.forward))

    def stop_recording(self) -> Path | None:
        """Stop and write the recording atomically (``lod.camera_path.save_path``); returns its path."""
        from lod.camera_path import CameraPath, save_path

        self.recording = False
        if not self.recorded:
            self.say("recording stopped: no frame recorded, nothing written")
            return None
        path = self.record_path or _free_path(self.out_dir, f"camera-{_stamp()}", ".json")
        save_path(path, CameraPath(self.recorded))
        self.saved_paths.append(path)
        self.say(f"wrote camera path {path} ({len(self.recorded)} keys, {self.recorded[-1][0]:.2f} s); "
                 f"replay it with [camera] path_file")
        return path

    # -- HUD -----------------------------------------------------------------------------------------------------------
    def settings_line(self) -> str:
        s = self.settings
        return (f"lod {s.lod_mode}  splat {s.splat_size:g}px  PoE {s.poe:g}px  kf {s.keyframe_interval}  "
                f"occlusion {'on' if s.occlusion else 'off'}  freeze {'on' if s.freeze else 'off'}  "
                f"colour {s.color_by}  raster {'compute' if s.compute_raster else 'hardware'}")


# ---------------------------------------------------------------------------------------------------------------------
# the app: window + engine + controller
# ---------------------------------------------------------------------------------------------------------------------


@dataclass
class FlyFrame:
    """What one fly-through frame did.

    drawlist : lod.drawlist.DrawList drawn
    stages : dict of seconds: simulate, select, upload, draw, finish, observe (mode auto and the budget learn
        the frame's cost), blit, hud, total
    stepped : bool, the simulation advanced this frame
    screenshot : Path or None
    """

    drawlist: object
    stages: dict = field(default_factory=dict)
    stepped: bool = False
    screenshot: Path | None = None


class FlyApp:
    """The fly-through: an Engine rendering into a glfw Window, driven by a FlyController.

    Parameters
    ----------
    engine : crowd.engine.Engine
    window : render.window.Window (its context renders the frames)
    out_dir : folder for screenshots and recordings
    record_path : recording file (default: timestamped in ``out_dir``)
    echo : line printer for messages and help (default print)
    """

    def __init__(self, engine, window, out_dir, record_path=None, echo=print, budget_ms: float = 0.0):
        from crowd.fly_budget import FlyBudget
        from render.window import Hud

        self.engine = engine
        self.window = window
        size = window.framebuffer_size
        self.renderer = engine.open_renderer(size, ctx=window.ctx)
        self.hud = Hud(window.ctx)
        cam = engine.camera_at(engine.world.time)
        self.controller = FlyController(engine, cam, size, out_dir, record_path, echo=echo)
        window.attach(self.controller)
        #: the frame budget (crowd.fly_budget; ``budget_ms`` 0: the scene's mode as written)
        self.budget = self.controller.budget = FlyBudget(engine, budget_ms, self.controller.say)
        self.frames = 0
        self.fps = 0.0  # frames per wall-clock second over the last RATE_FRAMES frames (0 before the second)
        self._starts: deque = deque(maxlen=RATE_FRAMES + 1)  # perf_counter at the start of recent frames
        self.periods: list = []  # wall seconds from each frame's start to the next's (the exit summary)
        self.last = None
        self._frozen = None
        self._last_stages: dict = {}
        self._hud_lines = None  # text shown, refreshed every HUD_REFRESH seconds or on input
        self._hud_revision = -1
        self._hud_clock = 0.0

    @property
    def size(self) -> tuple:
        return self.renderer.size

    def _apply_resize(self) -> None:
        c = self.controller
        if c.pending_size is not None and tuple(c.pending_size) != tuple(self.renderer.size):
            self.renderer = self.engine.open_renderer(c.pending_size, ctx=self.window.ctx)
            c.size = tuple(c.pending_size)
        c.pending_size = None

    def hud_lines(self) -> list:
        c, e = self.controller, self.engine
        st = self._last_stages
        ms = lambda k: f"{st.get(k, 0.0) * 1e3:.1f}"
        flags = ("  PAUSED" if c.paused else "") + (f"  REC {len(c.recorded)}" if c.recording else "")
        dl = self.last.drawlist if self.last is not None else None
        s = dl.stats if dl is not None else {}
        p = c.position
        lines = [
            f"{e.scene.name}  {self.fps:5.1f} fps  {self.budget.hud()}  frame {e.world.frame}  "
            f"t {e.world.time:.2f} s  {self.size[0]}x{self.size[1]}{flags}",
            f"ms  simulate {ms('simulate')}  select {ms('select')}  upload {ms('upload')}  draw {ms('draw')}  "
            f"finish {ms('finish')}  hud {ms('hud')}  total {ms('total')}",
            f"drawn  {s.get('instances', 0):,} instances ({s.get('culled', 0):,} culled)  "
            f"{s.get('triangles', 0):,} triangles ({s.get('raster_triangles', 0):,} in compute)  "
            f"{s.get('points', 0):,} points  {s.get('batches', 0)} batches",
            c.settings_line(),
            f"camera  ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f})  "
            f"yaw {math.degrees(c.yaw):.0f}  pitch {math.degrees(c.pitch):.0f}  speed {c.speed:.2g} m/s   H: help",
        ]
        lines += [m for m, _ in c.messages]
        if c.help_visible:
            lines += [""] + HELP_TEXT.splitlines()
        return lines

    def draw_hud(self, size, refresh: bool = False) -> tuple:
        """Draw the HUD over the window's frame; the text is rebuilt when ``refresh``, after
        any input, or every :data:`HUD_REFRESH` seconds of the controller clock. Returns its (w, h)."""
        c = self.controller
        if (refresh or self._hud_lines is None or c.revision != self._hud_revision
                or not 0.0 <= c.clock - self._hud_clock < HUD_REFRESH):
            self._hud_lines = self.hud_lines()
            self._hud_revision, self._hud_clock = c.revision, c.clock
        return self.hud.draw(self._hud_lines, size)

    def frame(self, dt: float) -> FlyFrame:
        """One frame: move the camera by ``dt`` seconds of input, step the simulation
        (unless paused), select (unless frozen), draw, blit, HUD, record, screenshot.
        Does not swap buffers (the window's back buffer holds the frame)."""
        c, e = self.controller, self.engine
        t0 = time.perf_counter()
        self._clock_frame(t0)
        self._apply_resize()
        c.update(dt)
        stepped = False
        if not c.paused or c.step_once:
            e.step()
            stepped = True
            c.step_once = False
        t1 = time.perf_counter()
        camera = c.camera()
        size = self.renderer.size
        if self.frames == 0:  # a scene's mode hopeless under the budget starts in auto (crowd.fly_budget)
            self.budget.before_first_frame(camera, size)
        camera, _ = e.terrain_frame(camera, self.renderer)  # after: auto under the budget draws it view-dependently
        if e.settings.freeze and self._frozen is not None:
            dl = reframe(self._frozen, camera, size)
        else:
            dl = e.select(camera, size)
            self._frozen = dl
        apply_tints(dl, e.settings.color_by, statics=e.static_keys)
        t2 = time.perf_counter()
        r = self.renderer.draw(dl, e.scene.render.background)
        t3 = time.perf_counter()
        # mode auto learns its costs (and holds its budget) from the frames drawn here too; another mode that
        # misses the budget gives way to auto (crowd.fly_budget)
        self.budget.observe(e.observe(dl, t2 - t1, r), dl)
        t_obs = time.perf_counter()
        self.window.blit(self.renderer.fbo)
        t4 = time.perf_counter()
        stages = {"simulate": t1 - t0, "select": t2 - t1, "upload": float(r.get("upload") or 0.0),
                  "draw": float(r.get("draw") or 0.0), "finish": float(r.get("finish") or 0.0),
                  "observe": t_obs - t3, "blit": t4 - t_obs}
        result = FlyFrame(dl, stages, stepped)
        self.last = result
        if c.hud_visible:
            self.draw_hud(size)
        t5 = time.perf_counter()
        stages["hud"] = t5 - t4
        c.record(camera)
        if c.screenshot_requested:
            c.screenshot_requested = False
            result.screenshot = self.screenshot()
        stages["total"] = time.perf_counter() - t0
        self._last_stages = stages
        self.frames += 1
        return result

    def _clock_frame(self, start: float) -> None:
        """Note a frame's start: the rate shown is the frames begun over the wall-clock time they spanned,
        over the last :data:`RATE_FRAMES` (a rate from whole periods, not an average of per-frame rates, which
        a first short period throws off for many frames)."""
        if self._starts:
            self.periods.append(start - self._starts[-1])
        self._starts.append(start)
        span = self._starts[-1] - self._starts[0]
        self.fps = (len(self._starts) - 1) / span if span > 0.0 else 0.0

    def summary(self) -> str:
        """The run's frame count, median frame time and rate (wall clock from one frame's start to the next)."""
        if not self.periods:
            return f"{self.frames} frames"
        med = float(np.median(self.periods))
        return f"{self.frames} frames, median frame {med * 1e3:.1f} ms ({1.0 / med:.1f} fps)"

    def screenshot(self, path=None) -> Path:
        """Write the last rendered frame (without HUD) as PNG, atomically; returns the path."""
        c = self.controller
        path = Path(path) if path is not None else _free_path(c.out_dir, f"screenshot-{_stamp()}", ".png")
        from crowd.images import write_png

        path.parent.mkdir(parents=True, exist_ok=True)
        write_png(path, self.renderer.read_pixels())
        c.say(f"wrote screenshot {path}")
        return path

    def run(self, max_frames: int | None = None) -> int:
        """The interactive loop until the window closes, Esc, or ``max_frames``; returns frames drawn."""
        w = self.window
        prev = time.perf_counter()
        n = 0
        while not (w.should_close or self.controller.quit_requested) and (max_frames is None or n < max_frames):
            w.poll()
            now = time.perf_counter()
            dt, prev = now - prev, now
            if self.controller.pending_size is None and 0 in w.framebuffer_size:
                time.sleep(0.05)  # minimised
                continue
            self.frame(dt)
            w.swap()
            n += 1
            check_interrupt()  # an interrupt another library swallowed stops the fly-through here (crowd.errors)
        return n

    def close(self) -> None:
        """Save an unfinished recording, release GL objects (HUD, renderer), keep the window."""
        if self.controller.recording:
            self.controller.stop_recording()
        self.hud.release()
        self.engine.close()


def fly(scene_path, size=None, out=None, record=None, frames=None, echo=print, budget=None) -> int:
    """``crowd fly``: open a window, build the scene's engine and fly until closed; returns the exit code.

    Parameters
    ----------
    scene_path : scene file
    size : (w, h) window size, default the scene's ``[render] size``
    out : folder for screenshots and recordings, default ``<output dir>-fly`` (e.g. ``out/quickstart-fly``)
    record : path of the camera recording (default a timestamped file in ``out``)
    frames : stop after this many frames (scripted runs), default: until closed
    budget : frame budget in ms (``crowd.fly_budget``), default :data:`crowd.fly_budget.DEFAULT_BUDGET_MS`;
        0 draws the scene's mode as written
    """
    from crowd.engine import Engine
    from crowd.fly_budget import DEFAULT_BUDGET_MS
    from crowd.scene import load_scene
    from render.window import Window, WindowError, display_available

    scene = load_scene(scene_path).with_overrides(size=size)
    if not display_available():
        print(no_display_message(str(scene_path)), file=sys.stderr)
        return EXIT_NO_DISPLAY
    out_dir = Path(out).absolute() if out is not None else scene.output_dir.with_name(scene.output_dir.name + "-fly")
    try:
        window = Window(scene.render.size, title=f"crowd fly {scene.name}")
    except WindowError as e:
        print(no_display_message(str(scene_path), str(e)), file=sys.stderr)
        return EXIT_NO_DISPLAY
    app = None
    try:
        engine = Engine(scene, quiet=False)
        app = FlyApp(engine, window, out_dir, record_path=record, echo=echo,
                     budget_ms=DEFAULT_BUDGET_MS if budget is None else budget)
        echo(f"crowd fly {scene.name}: OpenGL {window.gl_version[0]}.{window.gl_version[1]} core "
             f"({window.ctx.info['GL_RENDERER']}); press H for help")
        app.run(max_frames=frames)
        echo(f"crowd fly {scene.name}: {app.summary()}")
    except KeyboardInterrupt:
        print("crowd fly: interrupted", file=sys.stderr)
        return 130
    finally:
        if app is not None:
            app.close()
        window.close()
    return 0
