"""The engine's side of a changing agent count (``sim.population``): what follows the agents that left and
entered after each frame's simulation, and the counts telemetry writes.

- selectors with per-instance memory (``remap_agents(src, state)``, e.g. the keyframed selection) keep it for
  the agents that stayed;
- the colour-variation words are by stable id (``lod.variation.variation_table(..., ids=)``), so an agent keeps
  its colour whatever its index;
- frames.csv counts ``agents`` (alive this frame), ``entered`` (added by a source in it), ``exited`` (reached an
  exit in it: the frame PedPy sees them cross an exit line), ``left`` (removed at its start: they reached an exit
  two frames before, walking on through it for one frame), so agents(f) = agents(f-1) + entered(f) - left(f);
  summary.json the journeys' totals.

A scene whose count never changes pays one attribute test per frame.
"""
from __future__ import annotations

from crowd.errors import SceneError


def check_journeys(scene, world) -> None:
    """Refuse (one line naming the first problem, and how many more) a scene where some agents cannot reach a
    stage of their journey (``sim.journeys.reach``), before anything runs."""
    j = world.resources.get("journeys")
    if j is None:
        return
    from sim.journeys.reach import problems

    found = problems(j, world)
    if found:
        key, message = found[0]
        more = f" (and {len(found) - 1} more unreachable leg(s))" if len(found) > 1 else ""
        raise SceneError(scene.path, key, message + more)


def after_step(engine) -> None:
    """Follow the agents that left or entered in the last step (module docstring)."""
    from sim.population import take_changes

    world = engine.world
    if world.agents_changed is None:
        return
    src = take_changes(world)
    st = world.state
    selectors = {id(s): s for _, s in engine._modes.values()}
    selectors.setdefault(id(engine.selector), engine.selector)
    for selector in selectors.values():
        f = getattr(selector, "remap_agents", None)
        if callable(f):
            f(src, st)
    if getattr(engine, "_tint_table", None) is not None:
        from lod.variation import variation_table

        vs = [dict(c.variation) if c.variation else None for c in engine.scene.characters]
        engine._tint_table = variation_table(engine.scene.seed, st.character, vs, ids=st.ids)
        if engine.renderer is not None:
            engine.renderer.tint_table = engine._tint_table


def changing_count(world) -> bool:
    """Whether agents can leave and enter in this world (journeys' sources and exits, a replayed recording)."""
    return "journeys" in world.resources or "replay" in world.resources


def frame_counts(world) -> dict:
    """{"agents", "entered", "exited", "left"} of the frame just simulated (telemetry counts). Recorded people
    (``sim.replay``) count as entered at their first recorded frame and as exited and left after their last."""
    out = {"agents": world.state.n, "entered": 0, "exited": 0, "left": 0}
    j = world.resources.get("journeys")
    for k, v in (j.take_frame_counts() if j is not None else {}).items():
        out[k] = out.get(k, 0) + v
    r = world.resources.get("replay")
    if r is not None:
        c = r.take_frame_counts()
        out["entered"] += c["entered"]
        out["exited"] += c["left"]
        out["left"] += c["left"]
    return out


def summary(world) -> dict:
    """summary.json entries of the agent count: ``agents_final``, the journeys' totals and the replay's (when the
    scene has them)."""
    j = world.resources.get("journeys")
    out = {"agents_final": world.state.n}
    if j is not None:
        out["journeys"] = j.summary()
    r = world.resources.get("replay")
    if r is not None:
        out["replay"] = r.summary()
    return out


def entering_clips(world) -> dict:
    """{character index: {clip index, ...}} the agents that enter later play (journeys' sources, recorded
    people; LOD modes build what is played)."""
    j = world.resources.get("journeys")
    out = {}
    for s in (j.sources if j is not None else []):
        out.setdefault(int(s.cfg["character"]), set()).add(int(s.cfg.get("clip_index", 0)))
    r = world.resources.get("replay")
    for t in (r.tracks if r is not None else []):
        for c, k in t.played:
            out.setdefault(c, set()).add(k)
    return out
