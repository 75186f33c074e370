"""Agents that leave and enter: the crowd's arrays compacted, each agent named by a stable id.

``CrowdState`` holds only the agents alive. When some leave (an exit) and others enter (a source), the state
keeps the survivors in their order, appends the newcomers, and each agent keeps its id
(:attr:`sim.state.CrowdState.ids`: its index at the start; newcomers get fresh ids, never reused). Only
:func:`apply` changes the count, and it tells everyone who keeps per-agent arrays across steps or frames:

    src : (n_now,) int64, each current agent's index in the state before the change, -1 for an entered agent

Every ``world.resources`` value with a ``remap_agents(src)`` method is called with it (sim side: avoidance's
body radii and animation base rates, the journeys' per-agent stages); :attr:`sim.world.World.agents_changed`
composes the changes of a frame's sub-steps (:func:`compose`) until the engine takes them
(:func:`take_changes`) and hands them on (LOD selectors with per-instance memory, colour words by id).

Why compaction rather than a capacity with an active mask: nothing anywhere has to honour a mask (the
simulation kernels, neighbour grids, LOD selectors and draw paths all see only live agents, so an agent that
left cannot be simulated, avoided or drawn); a scene that never changes its count stores and runs nothing
extra. The price is an O(n) copy on the steps whose count changes (``scripts/bench_journeys.py``).
"""
from __future__ import annotations

import numpy as np

#: per-agent attributes of ``CrowdState`` other code may have attached and that compaction keeps consistent
#: by dropping: placement groups and hierarchies describe contiguous index ranges of the initial crowd
_RANGE_ATTRIBUTES = ("groups", "hierarchies", "tracks")


def compose(first: np.ndarray | None, then: np.ndarray | None) -> np.ndarray | None:
    """The src of two changes one after the other (``first`` maps state 1 to state 0, ``then`` state 2 to 1):
    (n2,) int64, -1 for agents that entered in either; None stands for no change."""
    if first is None:
        return then
    if then is None:
        return first
    then = np.asarray(then, np.int64)
    out = np.full(then.shape[0], -1, np.int64)
    ok = then >= 0
    out[ok] = np.asarray(first, np.int64)[then[ok]]
    return out


def resize(state, keep: np.ndarray | None = None, new=None) -> np.ndarray:
    """Change ``state`` in place: keep the agents ``keep`` ((k,) int64 indices, increasing; None = all), then
    append the agents of ``new`` (a ``CrowdState``, its ids ignored: they get the next fresh ids). Returns src.

    The arrays are replaced by new ones (never grown in place), so views taken before stay valid and unchanged.
    """
    n = state.n
    ids = state.ids
    if keep is None:
        keep = np.arange(n, dtype=np.int64)
    else:
        keep = np.asarray(keep, np.int64)
        if keep.size and (keep.min() < 0 or keep.max() >= n or np.any(np.diff(keep) <= 0)):
            raise ValueError(f"keep: expected increasing indices in 0 ..< {n}")
    m = 0 if new is None else new.n
    next_id = state.next_id
    k = keep.shape[0]
    for name, a in state.arrays().items():
        out = np.empty((k + m,) + a.shape[1:], a.dtype)  # one allocation, each byte written once
        np.take(a, keep, axis=0, out=out[:k])
        if m:
            out[k:] = np.asarray(getattr(new, name), a.dtype).reshape((m,) + a.shape[1:])
        setattr(state, name, out)
    state._ids = np.concatenate([ids[keep], np.arange(next_id, next_id + m, dtype=np.int64)])
    state._next_id = next_id + m
    for attr in _RANGE_ATTRIBUTES:
        if hasattr(state, attr):
            setattr(state, attr, [])
    return np.concatenate([keep, np.full(m, -1, np.int64)])


def apply(world, keep: np.ndarray | None = None, new=None) -> np.ndarray | None:
    """Agents ``keep`` stay, ``new`` enter (:func:`resize` on ``world.state``); every resource with
    ``remap_agents`` is told; the change is composed into ``world.agents_changed``. Returns src, or None when
    nothing changed (``keep`` is everyone and ``new`` is empty)."""
    st = world.state
    if (keep is None or len(keep) == st.n) and (new is None or new.n == 0):
        return None
    src = resize(st, keep, new)
    for r in list(world.resources.values()):
        f = getattr(r, "remap_agents", None)
        if callable(f):
            f(src, st)
    world.agents_changed = compose(getattr(world, "agents_changed", None), src)
    return src


def take_changes(world) -> np.ndarray | None:
    """The composed src of every change since the last call (None: the count and order did not change)."""
    src = getattr(world, "agents_changed", None)
    world.agents_changed = None
    return src


def remap_rows(a: np.ndarray | None, src: np.ndarray, fill=0) -> np.ndarray | None:
    """Rows of a per-agent array after a change: ``a[src]``, with ``fill`` for the entered agents (-1)."""
    if a is None:
        return None
    src = np.asarray(src, np.int64)
    out = np.empty((src.shape[0],) + a.shape[1:], a.dtype)
    ok = src >= 0
    out[ok] = a[src[ok]]
    out[~ok] = fill
    return out
