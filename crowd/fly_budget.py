"""The fly-through's frame budget (``crowd fly --budget MS``): a person watching gets an interactive rate by
default, not a slide show of a scene written for measurement.

The budget covers what mode auto trades for time: a frame's LOD selection and rendering, the same seconds
``crowd run`` reports to auto (:meth:`crowd.engine.Engine.observe`); the simulation, the window's blit and
the HUD are the scene's and the window's own. With a budget > 0:

- a scene in mode auto draws under it (:meth:`lod.auto.mode.AutoSelector.set_budget`: the pixel bound
  adapts to the measured frames);
- a scene in another mode is drawn in its own mode while that mode holds the budget. When it does not -- the
  median of :data:`CHECK_FRAMES` frames after the first :data:`SKIP_FRAMES` over the budget by more than
  :data:`TOLERANCE`, or one such frame over it by more than a factor :data:`URGENT` (a scene that draws in
  seconds is not watched for five frames) -- the fly-through switches to mode auto under the budget and says
  so (HUD and console);
- a mode picked by hand (M) is drawn as picked, never switched; auto picked by hand draws under the budget;
- a budget no plan of auto can meet is said once (HUD and console); auto then draws its cheapest plan
  (:mod:`lod.auto.control`, "Under a frame budget");
- while auto draws under the budget, a terrain the scene draws at full resolution is drawn view-dependently
  (the bisection hierarchy of Friedrich, Polthier & Schmies at the scene's ``lod_tau``, as ``[terrain] lod =
  "bisection"`` would; :meth:`crowd.engine.Engine.set_terrain_lod`), said on the HUD: on the stampede the
  257 x 257 grid's 131 K triangles cost 13 ms a frame, its selection at 1 px 4.6 K.

A scene whose own mode is hopeless under the budget does not make the person wait for it: before the first
frame, the scene's mode's selection is priced with auto's cost model (its calibration), and when the prediction
passes :data:`START_FACTOR` times the budget (a full-detail crowd of tens of millions of triangles: seconds a
frame) the fly-through starts in auto. Anything closer is judged by measured frames, as above.

Mode auto's representations are built (or read from the disk cache) and uploaded when the fly-through starts
with a budget, not when the scene's mode misses it, and each is drawn once, coarse, before the first frame
(:meth:`crowd.engine.Engine.warm_up`: its programs compiled, its buffers made): a switch in flight is then one
frame like the others, not a build of seconds, and the first frame a plan draws clusters or points is not one
of 100-300 ms more.

``--budget 0`` draws the scene's mode exactly as written (as ``crowd run`` does). ``crowd run`` and ``crowd
report`` keep the scene's mode: their job is to measure it.
"""
from __future__ import annotations

import math

import numpy as np

#: default budget of ``crowd fly``, milliseconds of selection + rendering: a 100 ms frame (10 fps) less what
#: the frame spends outside the budget (simulation, blit, HUD, swap)
DEFAULT_BUDGET_MS = 70.0
#: the keys move the budget by this factor, within BUDGET_RANGE milliseconds
BUDGET_STEP = 1.25
BUDGET_RANGE = (5.0, 5000.0)
#: frames of the scene's own mode not judged (the first draws build, upload and compile)
SKIP_FRAMES = 1
#: frames whose median decides that the scene's mode misses the budget
CHECK_FRAMES = 5
#: the median may exceed the budget by this fraction before the mode is switched
TOLERANCE = 0.10
#: one frame over the budget by more than this factor switches at once
URGENT = 3.0
#: before the first frame: a scene's mode predicted above this many times the budget starts in auto
START_FACTOR = 10.0
#: consecutive frames auto finds no plan within the budget before the HUD says so (its first frames price plans
#: never drawn pessimistically)
UNMEETABLE_FRAMES = 10


def parse_budget(text) -> float:
    """Milliseconds from ``--budget`` text: a finite number >= 0; ValueError (one sentence) otherwise."""
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise ValueError(f"expected milliseconds >= 0 (0: the scene's mode as written), got {text!r}") from None
    if not math.isfinite(v) or v < 0.0:
        raise ValueError(f"expected milliseconds >= 0 (0: the scene's mode as written), got {text!r}")
    return v


class FlyBudget:
    """The budget of one fly-through (module docstring).

    Parameters
    ----------
    engine : crowd.engine.Engine (its mode may be switched to auto)
    budget_ms : milliseconds >= 0; 0 = off
    say : callable(text) showing a message on the HUD (and the console)
    """

    def __init__(self, engine, budget_ms: float, say):
        self.engine = engine
        self.say = say
        self.budget_ms = parse_budget(budget_ms)
        #: the scene's own mode (what ``--budget 0`` draws)
        self.scene_mode = engine.settings.lod_mode
        #: mode auto is drawn in place of the scene's mode (it missed the budget)
        self.switched = False
        #: the person picked a mode (M): it is drawn as picked
        self.manual = False
        self._seen = 0
        self._samples: list = []
        self._said_unmeetable = False
        self._unmeetable = 0
        #: the terrain is drawn view-dependently (bisection; the scene's own choice, or auto's under the budget)
        self.terrain_lod = False
        self._prepare()
        self._apply()

    def _prepare(self) -> None:
        """Mode auto built and uploaded beside the scene's mode while a budget is on (module docstring)."""
        if self.budget_ms > 0.0 and self.auto() is None and "auto" in self.engine.lod_modes:
            self.engine.prepare_mode("auto")

    def auto(self):
        """The engine's mode-auto selector (inside a keyframed selection too), or None in another mode."""
        sel = self.engine.selector
        sel = getattr(sel, "inner", sel)
        return sel if hasattr(sel, "set_budget") else None

    def _apply(self) -> None:
        a = self.auto()
        if a is not None:
            a.set_budget(self.budget_ms)
        # auto under the budget covers the ground too: a full-resolution terrain drawn view-dependently
        self.terrain_lod = self.engine.set_terrain_lod(a is not None and self.budget_ms > 0.0)

    def before_first_frame(self, camera, size) -> None:
        """Draw auto's representations once, coarse (:meth:`crowd.engine.Engine.warm_up`), and price the scene's
        mode's first selection with auto's cost model; start in auto when it is hopeless (module docstring).
        Costs one selection and a coarse draw per representation."""
        if self.budget_ms <= 0.0 or self.manual or "auto" not in self.engine.lod_modes:
            return
        self.engine.warm_up("auto", camera, size)
        if self.auto() is not None:
            return
        from lod.auto.cost_model import FEATURES, features

        e = self.engine
        a = e.prepare_mode("auto")
        a = getattr(a, "inner", a)  # inside a keyframed selection
        x = features(e.select(camera, size), extended=True)
        secs = a.fit.predict(x)[0] if a.fit is not None else float(a.model.predict_counts(*x[:len(FEATURES)]))
        if math.isfinite(secs) and 1e3 * secs > START_FACTOR * self.budget_ms:
            self._switch(1e3 * secs, predicted=True)

    def observe(self, seconds: float, drawlist=None) -> None:
        """A frame's selection + rendering seconds (and its DrawList): switches the scene's mode to auto when it
        misses the budget; says once when auto finds no plan that can meet it."""
        auto = drawlist.stats.get("auto") if drawlist is not None else None
        self._unmeetable = self._unmeetable + 1 if isinstance(auto, dict) and auto.get("unmeetable") else 0
        if self._unmeetable >= UNMEETABLE_FRAMES and not self._said_unmeetable and self.budget_ms > 0:
            self._said_unmeetable = True
            self.say(f"no plan of mode auto fits the {self.budget_ms:g} ms budget here: drawing the cheapest "
                     f"(0 raises the budget)")
        if (self.budget_ms <= 0.0 or self.switched or self.manual or self.auto() is not None
                or not math.isfinite(seconds) or (drawlist is not None and drawlist.warm_up)):
            return  # (a warm-up frame's time carries a one-time cost: lod.drawlist.DrawList.warm_up)
        self._seen += 1
        if self._seen <= SKIP_FRAMES:
            return
        ms = 1e3 * float(seconds)
        self._samples.append(ms)
        recent = self._samples[-CHECK_FRAMES:]
        if ms > URGENT * self.budget_ms:
            self._switch(ms)
        elif len(recent) == CHECK_FRAMES and float(np.median(recent)) > (1.0 + TOLERANCE) * self.budget_ms:
            self._switch(float(np.median(recent)))

    def _switch(self, ms: float, predicted: bool = False) -> None:
        self.engine.set_lod_mode("auto")
        self._apply()
        self.switched = True
        what = "predicted" if predicted else "a frame"
        self.say(f"mode {self.scene_mode} misses the {self.budget_ms:g} ms budget ({ms:.0f} ms {what}): "
                 f"drawing mode auto under it (--budget 0 draws the scene's mode)")

    def mode_picked(self) -> None:
        """The person picked a mode by hand: drawn as picked (auto under the budget)."""
        self.manual = True
        self.switched = False
        self._apply()

    def change(self, direction: int) -> None:
        """Raise (``direction`` > 0) or lower the budget by :data:`BUDGET_STEP`; from off, raising turns it on at
        :data:`DEFAULT_BUDGET_MS`."""
        if self.budget_ms <= 0.0:
            if direction <= 0:
                return
            self.budget_ms = DEFAULT_BUDGET_MS
            self._prepare()
        else:
            self.budget_ms = float(np.clip(self.budget_ms * BUDGET_STEP ** int(np.sign(direction)), *BUDGET_RANGE))
        self._samples.clear()
        self._seen = 0
        self._said_unmeetable = False
        self._apply()
        self.say(f"frame budget {self.budget_ms:g} ms")

    def hud(self) -> str:
        """The HUD's words for the budget: its value, what is drawn under it, auto's current error bound."""
        if self.budget_ms <= 0.0:
            return "budget off"
        text = f"budget {self.budget_ms:g} ms"
        if self.switched:
            text += f" (auto in place of {self.scene_mode})"
        a = self.auto()
        if a is not None:
            text += f"  bound {a.bound:.3g} px"
            if self._unmeetable >= UNMEETABLE_FRAMES:
                text += " (no plan fits: the cheapest)"
        if self.terrain_lod:
            text += "  terrain bisection"
        return text
