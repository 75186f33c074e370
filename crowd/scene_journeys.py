"""``[[stages]]``, ``[[journeys]]`` and ``[[sources]]`` of a scene, parsed for :mod:`crowd.scene`.

They configure the ``journeys`` effect (``sim.journeys``; docs/scenes.md "Journeys"): the validated tables
are handed to it as the ``stages``, ``journeys`` and ``sources`` keys of its effect parameters (stage and
journey names resolved to indices, characters to indices and scales). Every problem is one line naming the
key, through the parser's ``fail(key, message)``, before anything is built: unknown or missing keys, a
stage name no stage has, an exit anywhere but at the end of a journey, an exit of zero width, a polygon that
is not simple, a source outside the walkable area (entirely inside obstacles), the effect listed without
journeys or journeys without the effect, ``journeys`` beside ``goals`` (both steer) or ``instancing``
(its agent groups are fixed index ranges).
"""
from __future__ import annotations

import math

from crowd.measurement import parse_line, parse_polygon
from sim.params import Param, ParamError, validate

class _Time(Param):
    """Seconds or a distribution table (checked by :func:`_time`)."""

    def check(self, key, value):
        return value


STAGE_KINDS = ("waypoint", "exit", "wait", "queue")
STAGE_SCHEMA = {
    "name": Param("str", doc="unique name, used by [[journeys]] stages"),
    "kind": Param("str", choices=STAGE_KINDS),
    "point": Param("vec2", None, doc="waypoint: [x, z]"),
    "radius": Param("float", 0.5, min=1e-3, max=1000.0, doc="waypoint: reached within this distance, metres"),
    "polygon": Param("list", None, doc="exit: area agents leave in; wait: the waiting area"),
    "line": Param("list", None, doc="exit: door [[x1, z1], [x2, z2]]; queue: polyline from its head"),
    "slots": Param("list", None, doc="wait / queue: explicit places [[x, z], ...] (queue: head first)"),
    "spacing": Param("float", 0.8, min=0.05, max=100.0, doc="wait: lattice of slots; queue: place spacing, m"),
    "capacity": Param("int", None, min=1, max=100_000, doc="wait / queue: at most this many slots"),
    "time": _Time("table", 0.0, doc="wait: waiting time; queue: service time at the head; seconds or "
                  "{kind = fixed|uniform|exponential|normal, ...}"),
    "release_at": Param("list", None, doc="wait: times at which the waiting agents are released, seconds"),
}
#: keys each kind accepts besides name and kind
KIND_KEYS = {"waypoint": ("point", "radius"), "exit": ("polygon", "line"),
             "wait": ("polygon", "slots", "spacing", "capacity", "time", "release_at"),
             "queue": ("line", "slots", "spacing", "capacity", "time")}
TIME_SCHEMAS = {"fixed": ("value",), "uniform": ("min", "max"), "exponential": ("mean",), "normal": ("mean", "sd")}
JOURNEY_SCHEMA = {
    "name": Param("str", doc="unique name, used by [[sources]] journey"),
    "stages": Param("list", doc="entries: a stage name, or a choice {name = weight, ...} / [name, ...]"),
    "placements": Param("list", [], doc="indices of the [[placement]] tables whose agents follow the journey"),
    "loop": Param("bool", False, doc="start again at the first entry after the last (no exit)"),
    "speed": Param("float", None, min=0.0, max=100.0, doc="desired speed, m/s; default the effect's speed"),
}
SOURCE_SCHEMA = {
    "name": Param("str", doc="unique name (summary.json)"),
    "character": Param("str", doc="a [[characters]] name"),
    "clip": Param("str", None, doc="clip the agents play; default the character's first"),
    "journey": Param("str", doc="a [[journeys]] name"),
    "rate": Param("float", min=1e-6, max=1e6, doc="agents per second"),
    "process": Param("str", "uniform", choices=("uniform", "poisson"), doc="evenly spaced or Poisson arrivals"),
    "start": Param("float", 0.0, min=0.0, doc="first arrival, seconds"),
    "stop": Param("float", None, min=0.0, doc="no arrivals after this time, seconds"),
    "total": Param("int", None, min=1, doc="at most this many agents in all"),
    "capacity": Param("int", None, min=1, doc="at most this many of its agents alive at once"),
    "polygon": Param("list", None, doc="spawn area [[x, z], ...]"),
    "line": Param("list", None, doc="spawn line [[x1, z1], [x2, z2]]"),
    "scale": Param("float", 1.0, min=1e-3, max=1000.0, doc="times the character's scale"),
    "heading": Param("float", None, doc="yaw of entering agents, degrees; default facing their first stage"),
}


def parse_journeys(doc: dict, effects: list, placements: list, characters: list, fail) -> list:
    """``effects`` with the journeys effect's parameters completed from ``doc``'s tables (module docstring)."""
    tables = {k: doc.get(k) for k in ("stages", "journeys", "sources")}
    eff = next((e for e in effects if e.name == "journeys"), None)
    given = [k for k, v in tables.items() if v is not None]
    if eff is None:
        if given:
            fail(given[0], f"[[{given[0]}]] needs the effect 'journeys' in `effects`")
        return effects
    where = f"effects[{eff.index}]"
    for other in ("goals", "instancing"):
        o = next((e for e in effects if e.name == other), None)
        if o is not None:
            why = "both steer the agents" if other == "goals" else \
                "its agent groups are fixed index ranges, while journeys add and remove agents"
            fail(f"effects[{o.index}]", f"effect {other!r} cannot be listed with 'journeys' ({why})")
    for k, v in tables.items():
        if v is not None and (not isinstance(v, list) or not all(isinstance(t, dict) for t in v)):
            fail(k, f"expected an array of tables [[{k}]], got {v!r}")
    if not tables["journeys"]:
        fail(where, "effect 'journeys' needs at least one [[journeys]] table (and the [[stages]] it names)")
    stages = [_stage(t, i, fail) for i, t in enumerate(tables["stages"] or [])]
    names = _unique([s["name"] for s in stages], "stages", fail)
    journeys = [_journey(t, i, names, stages, len(placements), fail) for i, t in enumerate(tables["journeys"])]
    jnames = _unique([j["name"] for j in journeys], "journeys", fail)
    claimed = {}
    for i, j in enumerate(journeys):
        for p in j["placements"]:
            if p in claimed:
                fail(f"journeys[{i}].placements", f"placement[{p}] already follows journeys[{claimed[p]}]")
            claimed[p] = i
    chars = [c.name for c in characters]
    obstacles = next((e for e in effects if e.name == "obstacles"), None)
    sources = [_source(t, i, chars, characters, jnames, obstacles, fail) for i, t in enumerate(tables["sources"] or [])]
    _unique([s["name"] for s in sources], "sources", fail)
    _walkable_checks(effects, stages, sources, fail)
    import dataclasses

    params = {**eff.params, "stages": stages, "journeys": journeys, "sources": sources}
    return [dataclasses.replace(e, params=params) if e is eff else e for e in effects]


def _unique(names: list, key: str, fail) -> dict:
    seen = {}
    for i, n in enumerate(names):
        if not n.strip():
            fail(f"{key}[{i}].name", "expected a non-empty string")
        if n in seen:
            fail(f"{key}[{i}].name", f"duplicate name {n!r} (also {key}[{seen[n]}])")
        seen[n] = i
    return seen


def _check(schema: dict, t: dict, where: str, fail) -> dict:
    try:
        return validate(schema, t, where)
    except ParamError as e:
        fail(e.key, e.message)


def _stage(t: dict, i: int, fail) -> dict:
    where = f"stages[{i}]"
    s = _check(STAGE_SCHEMA, t, where, fail)
    kind = s["kind"]
    for k in t:
        if k not in ("name", "kind") and k not in KIND_KEYS[kind]:
            fail(f"{where}.{k}", f"not a key of a {kind} stage; accepted: {', '.join(KIND_KEYS[kind])}")
    out = {"name": s["name"], "kind": kind, "radius": s["radius"], "spacing": s["spacing"],
           "capacity": s["capacity"], "time": _time(t.get("time", 0.0), f"{where}.time", fail),
           "point": None, "polygon": None, "line": None, "slots": None, "release_at": None}
    if kind == "waypoint":
        if s["point"] is None:
            fail(f"{where}.point", "a waypoint needs `point = [x, z]`")
        out["point"] = list(s["point"])
    elif kind == "exit":
        if (s["polygon"] is None) == (s["line"] is None):
            fail(where, "an exit needs exactly one of `polygon` (an area agents leave in) or `line` (a door)")
        if s["polygon"] is not None:
            out["polygon"] = [list(p) for p in parse_polygon(f"{where}.polygon", s["polygon"], fail)]
        else:
            out["line"] = [list(p) for p in parse_line(f"{where}.line", s["line"], fail,
                                                       "an exit of zero width: expected two distinct points")]
    else:
        if s["slots"] is not None:
            out["slots"] = [list(Param("vec2").check(f"{where}.slots[{k}]", p))
                            for k, p in enumerate(_list(s["slots"], f"{where}.slots", fail))]
            if not out["slots"]:
                fail(f"{where}.slots", "expected at least one [x, z] slot")
        elif kind == "wait":
            if s["polygon"] is None:
                fail(where, "a waiting area needs `polygon` (slots on a lattice of `spacing`) or `slots`")
            out["polygon"] = [list(p) for p in parse_polygon(f"{where}.polygon", s["polygon"], fail)]
            from sim.journeys.geometry import grid_in_polygon
            import numpy as np

            if grid_in_polygon(np.asarray(out["polygon"]), s["spacing"]).shape[0] == 0:
                fail(f"{where}.spacing", f"no slot {s['spacing']:g} m apart fits in the polygon")
        else:
            if s["line"] is None:
                fail(where, "a queue needs `line` (a polyline from its head) or `slots`")
            pts = [tuple(Param("vec2").check(f"{where}.line[{k}]", p)) for k, p in
                   enumerate(_list(s["line"], f"{where}.line", fail))]
            if len(pts) < 2 or sum(math.dist(a, b) for a, b in zip(pts, pts[1:])) <= 0.0:
                fail(f"{where}.line", "a queue line needs at least two points and a non-zero length")
            out["line"] = [list(p) for p in pts]
        if kind == "wait" and t.get("release_at") is not None:
            r = [Param("float", min=0.0).check(f"{where}.release_at[{k}]", x)
                 for k, x in enumerate(_list(t["release_at"], f"{where}.release_at", fail))]
            out["release_at"] = sorted(r)
    return out


def _list(v, key: str, fail) -> list:
    if not isinstance(v, list):
        fail(key, f"expected a list, got {v!r}")
    return v


def _time(v, key: str, fail) -> dict:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return {"kind": "fixed", "value": Param("float", min=0.0).check(key, v)}
    if not isinstance(v, dict):
        fail(key, f"expected seconds >= 0 or a table {{kind = {' | '.join(TIME_SCHEMAS)}, ...}}, got {v!r}")
    kind = v.get("kind")
    if kind not in TIME_SCHEMAS:
        fail(f"{key}.kind", f"expected one of {', '.join(map(repr, TIME_SCHEMAS))}, got {kind!r}")
    schema = {k: Param("float", min=0.0) for k in TIME_SCHEMAS[kind]}
    out = {"kind": kind, **_check(schema, {k: x for k, x in v.items() if k != "kind"}, key, fail)}
    if kind == "uniform" and out["max"] < out["min"]:
        fail(f"{key}.max", f"expected >= min ({out['min']:g}), got {out['max']:g}")
    return out


def _journey(t: dict, i: int, names: dict, stages: list, n_placements: int, fail) -> dict:
    where = f"journeys[{i}]"
    j = _check(JOURNEY_SCHEMA, t, where, fail)
    entries = []
    if not j["stages"]:
        fail(f"{where}.stages", "expected at least one stage")
    for k, e in enumerate(j["stages"]):
        key = f"{where}.stages[{k}]"
        if isinstance(e, str):
            opts = [(e, 1.0)]
        elif isinstance(e, list) and e and all(isinstance(x, str) for x in e):
            opts = [(x, 1.0) for x in e]
        elif isinstance(e, dict) and e:
            opts = [(x, Param("float", min=0.0).check(f"{key}.{x}", w)) for x, w in e.items()]
            if sum(w for _, w in opts) <= 0.0:
                fail(key, "expected a choice with a positive weight")
        else:
            fail(key, f"expected a stage name, a list of names or a table {{name = weight, ...}}, got {e!r}")
        for name, _ in opts:
            if name not in names:
                fail(key, f"unknown stage {name!r}; defined: {', '.join(map(repr, names)) or 'none'}")
        exits = [stages[names[x]]["kind"] == "exit" for x, _ in opts]
        if any(exits) and k != len(j["stages"]) - 1:
            fail(key, "an exit ends a journey: it can only be the last entry")
        if any(exits) and not all(exits):
            fail(key, "a choice of the last entry is either all exits or none")
        if any(exits) and j["loop"]:
            fail(f"{where}.loop", "a journey that ends at an exit cannot loop")
        entries.append([(names[x], w) for x, w in opts])
    placements = []
    for k, p in enumerate(j["placements"]):
        p = Param("int", min=0).check(f"{where}.placements[{k}]", p)
        if p >= n_placements:
            fail(f"{where}.placements[{k}]", f"no placement[{p}] ({n_placements} [[placement]] table(s))")
        placements.append(p)
    return {"name": j["name"], "stages": entries, "placements": placements, "loop": j["loop"], "speed": j["speed"]}


def _source(t: dict, i: int, chars: list, characters: list, journeys: dict, obstacles, fail) -> dict:
    where = f"sources[{i}]"
    s = _check(SOURCE_SCHEMA, t, where, fail)
    if s["character"] not in chars:
        fail(f"{where}.character", f"unknown character {s['character']!r}; defined: {', '.join(map(repr, chars))}")
    if s["journey"] not in journeys:
        fail(f"{where}.journey", f"unknown journey {s['journey']!r}; defined: {', '.join(map(repr, journeys))}")
    if (s["polygon"] is None) == (s["line"] is None):
        fail(where, "a source needs exactly one of `polygon` or `line` (where agents enter)")
    if s["stop"] is not None and s["stop"] < s["start"]:
        fail(f"{where}.stop", f"expected >= start ({s['start']:g}), got {s['stop']:g}")
    ci = chars.index(s["character"])
    out = {**s, "character": ci, "journey": journeys[s["journey"]], "scale": s["scale"] * characters[ci].scale}
    if s["polygon"] is not None:
        out["polygon"] = [list(p) for p in parse_polygon(f"{where}.polygon", s["polygon"], fail)]
    else:
        out["line"] = [list(p) for p in parse_line(f"{where}.line", s["line"], fail)]
    if obstacles is not None:
        _outside_check(out, f"{where}.{'polygon' if s['polygon'] is not None else 'line'}", obstacles, fail)
    return out


def _outside_check(src: dict, key: str, obstacles, fail) -> None:
    """A spawn area with no point clear of the obstacles lies outside the walkable area."""
    import numpy as np

    from sim.journeys.geometry import sample_polygon
    from sim.obstacles import ObstacleSet

    obs = ObstacleSet.from_config(obstacles.params)
    if obs.count == 0:
        return
    rng = np.random.default_rng(0)
    if src.get("polygon") is not None:
        pts = sample_polygon(np.asarray(src["polygon"]), rng, 256)
    else:
        a, b = np.asarray(src["line"], np.float64)
        pts = a + np.linspace(0.0, 1.0, 257)[:, None] * (b - a)
    if pts.shape[0] and not np.any(obs.sdf(pts[:, 0], pts[:, 1])[0] > 0.0):
        fail(key, f"the spawn area lies outside the walkable area: inside the obstacles of effects[{obstacles.index}]")


def _walkable_checks(effects: list, stages: list, sources: list, fail) -> None:
    """With ``routing`` (``crowd.scene_routing``): every stage shape and spawn area must lie in the walkable area
    (``sim.routing.geometry.shape_problem``: outside it, inside an obstacle, a door of zero width)."""
    try:
        from crowd.scene_routing import walkable_of
        from sim.routing.geometry import shape_problem
    except ImportError:  # no routing in this build: the obstacles check of the sources stands
        return
    area = walkable_of(effects)
    if area is None:
        return

    def check(key, kind, geom):
        problem = shape_problem(area, (kind, geom))
        if problem:
            fail(key, problem)

    for i, s in enumerate(stages):
        where = f"stages[{i}]"
        if s["point"] is not None:
            check(f"{where}.point", "point", tuple(s["point"]))
        for k, p in enumerate(s["slots"] or []):
            check(f"{where}.slots[{k}]", "point", tuple(p))
        if s["polygon"] is not None:
            check(f"{where}.polygon", "polygon", [tuple(p) for p in s["polygon"]])
        if s["line"] is not None:
            for k, (a, b) in enumerate(zip(s["line"], s["line"][1:])):
                check(f"{where}.line", "line", (tuple(a), tuple(b)))
    for i, s in enumerate(sources):
        if s.get("polygon") is not None:
            check(f"sources[{i}].polygon", "polygon", [tuple(p) for p in s["polygon"]])
        else:
            check(f"sources[{i}].line", "line", tuple(tuple(p) for p in s["line"]))


def entering_agents(scene) -> list:
    """[(character index, agents)] the scene's sources can add during its run at most (the memory guard's
    count: exits ignored; Poisson arrivals counted up to 5 standard deviations above their mean)."""
    eff = next((e for e in scene.effects if e.name == "journeys"), None)
    out = []
    for s in (eff.params.get("sources", []) if eff is not None else []):
        end = scene.frames * scene.dt if s.get("stop") is None else min(scene.frames * scene.dt, s["stop"])
        mean = max(0.0, end - s.get("start", 0.0)) * s["rate"]
        k = math.ceil(mean) + 1 if s.get("process", "uniform") == "uniform" else math.ceil(mean + 5 * math.sqrt(mean))
        for cap in ("total", "capacity"):
            if s.get(cap) is not None:
                k = min(k, int(s[cap]))
        out.append((int(s["character"]), int(k)))
    return out
