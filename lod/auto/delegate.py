"""Held pure plans of mode auto drawn by the single mode's own selector (issue 26: auto must not lose to the
mode it would draw anyway).

When :class:`lod.auto.control.PlanChooser` holds a pure plan (one representation wherever it is within the
bound, the triangle chain elsewhere) between two pricings, the frame's list is, by construction, what the
single mode of that representation selects at the same bound: the triangle chains' coarsest level within
the bound (:mod:`lod.chains.mode`), the VDR-AM cut at the bound (:mod:`lod.clusters.mode`), the point
hierarchies at the splat size the bound allows (:mod:`lod.points.mode`). The single modes select it with
less Python per instance group than auto's candidate machinery, which matters on scenes of a few
instances (poser4: 4 instances, 8-11 ms frames, auto's own selection 2-3 ms).

Whether the two really agree is not assumed: the first time a plan is held, both select the same frame and
their lists are compared batch by batch (representation, part, level, instances, triangles, points,
splat size); only a plan whose lists agree is delegated from then on, so a representation whose mode and
candidate differ (the point candidate with ``points_error = "splat+keyframes"``, the cluster candidate with
``cluster_error_scale``, a scene with instancing super nodes the triangle mode does not draw) simply keeps
auto's own path.
"""
from __future__ import annotations

import numpy as np


def signature(dl) -> list:
    """What a DrawList draws, comparable between selectors: per batch (rep, part, level, instance ids,
    triangles, points), sorted; plus the splat size."""
    out = sorted((b.rep, int(b.part), int(b.level), tuple(np.asarray(b.instance_ids).tolist()), int(b.triangles),
                  int(b.points)) for b in dl.batches if b.n_instances)
    return [out, (dl.options or {}).get("splat_size")]


class Delegates:
    """The single modes' selectors over auto's own representations (module docstring).

    Parameters
    ----------
    selectors : candidate name -> that mode's selector (``select(state, camera, size, statics)``)
    """

    def __init__(self, selectors: dict):
        self.selectors = {k: v for k, v in dict(selectors or {}).items() if v is not None}
        #: candidate name -> True (lists agree: delegate), False (they differ: never)
        self.verified: dict = {}
        self.delegated = 0

    def configure(self, name: str, bound: float, candidates) -> bool:
        """Set the selector of ``name`` to auto's bound this frame; False when it has no such setting."""
        sel = self.selectors.get(name)
        if sel is None:
            return False
        cand = next((c for c in candidates if c.name == name), None)
        if name == "points" and cand is not None and hasattr(sel, "splat_size"):
            p = cand.splat_size(bound)
            if p < 1:
                return False
            sel.splat_size = int(p)
        elif hasattr(sel, "poe"):
            sel.poe = float(bound) / float(getattr(cand, "error_scale", 1.0) or 1.0)
        else:
            return False
        return True

    def ready(self, name: str) -> bool:
        return self.verified.get(name) is True

    def pending(self, name: str) -> bool:
        return name in self.selectors and name not in self.verified

    def verify(self, name: str, own, state, camera, size, statics, bound: float, candidates) -> bool:
        """Compare the single mode's list with auto's own ``own`` of the same frame; remember the verdict."""
        ok = False
        if self.configure(name, bound, candidates):
            try:
                ok = signature(self.selectors[name].select(state, camera, size, statics)) == signature(own)
            except (AttributeError, TypeError, ValueError):
                ok = False
        self.verified[name] = ok
        return ok

    def select(self, name: str, state, camera, size, statics, bound: float, candidates):
        """The single mode's list of this frame (None when it cannot be configured)."""
        if not self.configure(name, bound, candidates):
            return None
        self.delegated += 1
        return self.selectors[name].select(state, camera, size, statics)

    def warm_lists(self, state, camera, size, statics, candidates, bound: float = 64.0) -> list:
        """One DrawList per single mode, each selected at the coarse ``bound`` (cheap to draw whatever the view):
        drawn once before the first frame, they compile the drawers' programs and create their buffers, so that
        the first frame a plan draws a representation is not one of 200-300 ms more (the exhibition's first
        cluster draw, 462 ms against 173 ms after; issue 49). The selectors' bound is set again before each
        use (:meth:`configure`)."""
        out = []
        for name in self.selectors:
            if self.configure(name, bound, candidates):
                out.append(self.selectors[name].select(state, camera, size, statics))
        return out


def delegated_stats(dl, plan: str, predicted: float, sd: float, bound: float, sel) -> dict:
    """``stats["auto"]`` of a delegated frame (the keys of :mod:`lod.auto.mode`'s telemetry)."""
    n = int(sum(b.n_instances for b in dl.batches if b.n_instances and int(b.instance_ids[0]) >= 0))
    a = {"levels": list(dl.stats.get("levels", [])), "representations": {plan: n}, "options": {},
         "predicted_ms": 1e3 * predicted, "predicted_sd_ms": 1e3 * sd, "bound": bound, "budget_ms": sel.budget_ms,
         "plan": plan, "state": "delegated", "incumbent": plan, "fade_from": None, "fade_t": 0.0,
         "threshold": None, "plans_ms": {plan: 1e3 * predicted}, "plans_sd_ms": {plan: 0.0}}
    if sel.explain:
        a["groups"] = {}
        a["model"] = sel.fit.state() if sel.fit is not None else None
    return a


__all__ = ["Delegates", "delegated_stats", "signature"]
