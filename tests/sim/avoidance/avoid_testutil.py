"""Helpers of the avoidance tests: worlds from scenes or arrays, overlap and obstacle checks."""
from __future__ import annotations

from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[3]
#: pairs may be closer than r_i + r_j by at most this fraction (the issue's 1 %)
TOLERANCE = 0.01


def world_from_arrays(xz, effects, characters=(), scale=None):
    """A World of agents at ``xz`` (n, 2) with ``effects`` [(name, cfg)] installed (validated)."""
    from sim.params import validate
    from sim.state import CrowdState
    from sim.systems import effect_module
    from sim.world import World

    xz = np.asarray(xz, np.float64)
    st = CrowdState.empty(xz.shape[0])
    st.position[:, 0], st.position[:, 2] = xz[:, 0], xz[:, 1]
    if scale is not None:
        st.scale[:] = scale
    w = World(state=st, characters=list(characters), seed=1)
    for name, cfg in effects:
        w.install(name, validate(effect_module(name).PARAMS, cfg, f"effects.{name}"))
    return w


def world_from_scene(name, model=None, avoidance=None, count=None, scene_edit=None):
    """The world of ``scenes/NAME.toml`` (no renderer). ``model``/``avoidance`` override the
    avoidance effect's parameters, ``count`` every random placement's count, ``scene_edit(doc)``
    edits the parsed TOML before validation."""
    import tomllib

    from crowd.engine import plan
    from crowd.scene import parse_scene
    from sim.world import World

    path = REPO / "scenes" / f"{name}.toml"
    doc = tomllib.loads(path.read_text())
    for e in doc.get("effects", []):
        if isinstance(e, dict) and e.get("name") == "avoidance":
            if model is not None:
                e["model"] = model
            e.update(avoidance or {})
    if count is not None:
        for p in doc["placement"]:
            if p["kind"] == "random":
                p["count"] = count
    if scene_edit is not None:
        scene_edit(doc)
    sc = parse_scene(doc, path)
    p = plan(sc)
    w = World(state=p.state, characters=p.characters, seed=sc.seed)
    w.resources["character_radius"] = [c.radius for c in sc.characters]
    for e in sc.effects:
        w.install(e.name, e.params)
    return sc, w


def min_gap_ratio(w) -> float:
    """Smallest |p_i - p_j| / (r_i + r_j) over all pairs (inf for fewer than 2 agents)."""
    from scipy.spatial import cKDTree

    r = w.resources["avoidance"].radius
    xz = w.state.position[:, [0, 2]]
    if xz.shape[0] < 2:
        return float("inf")
    pairs = cKDTree(xz).query_pairs(2.0 * float(r.max()), output_type="ndarray")
    if len(pairs) == 0:
        return float("inf")
    d = np.hypot(*(xz[pairs[:, 0]] - xz[pairs[:, 1]]).T)
    return float((d / (r[pairs[:, 0]] + r[pairs[:, 1]])).min())


def min_obstacle_clearance(w) -> float:
    """Smallest signed distance of an agent centre to an obstacle minus the obstacles' agent_radius
    (>= 0: no agent inside an obstacle; +inf without obstacles)."""
    obs = w.resources.get("obstacles")
    if obs is None or obs.count == 0:
        return float("inf")
    d, _, _ = obs.sdf(w.state.position[:, 0], w.state.position[:, 2])
    return float(d.min() - w.resources["obstacles.agent_radius"])


def run_checked(w, steps, dt, tol=TOLERANCE):
    """Step ``steps`` times; after every step no pair closer than (1 - tol)(r_i + r_j), no agent
    within the obstacles' agent radius (minus tol of it), all finite. Returns the worst ratio."""
    worst = float("inf")
    for k in range(steps):
        w.step(dt)
        w.state.check_finite()
        g = min_gap_ratio(w)
        worst = min(worst, g)
        assert g >= 1.0 - tol, f"step {k}: two agents at {g:.4f} x (r_i + r_j)"
        c = min_obstacle_clearance(w)
        ar = w.resources.get("obstacles.agent_radius", 0.0)
        assert c >= -tol * ar - 1e-9, f"step {k}: an agent {-c:.4f} m inside an obstacle's clearance"
    return worst
