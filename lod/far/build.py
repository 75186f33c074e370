"""The far tier of a mode's build (``[lod] far_pixels``; mode points and mode auto): the characters' far
representations and the per-frame split, and the merge of the split into a mode's DrawList."""
from __future__ import annotations

import numpy as np

from lod.far.rep import build_far_rep
from lod.far.select import FarSplit


def _clip_indices(rep, clips):
    """The clip indices (``CrowdState.clip``) of ``clips`` (None: all; names or indices) in a full-detail rep;
    names the rep does not have are left out (the mode's own build names them)."""
    if clips is None:
        return None
    names = list(getattr(rep, "clip_names", None) or getattr(rep, "anim_names", None) or [])
    return [names.index(c) if isinstance(c, str) else int(c) for c in clips if not isinstance(c, str) or c in names]


def build_far_split(characters, names, fps, clips, far_pixels: float) -> FarSplit | None:
    """The :class:`FarSplit` of the characters (their footprints measured on their full-detail reps, only for
    ``clips``: per character None (all) or the clips the scene plays), or None when ``far_pixels`` is 0."""
    if not float(far_pixels) > 0.0 or not characters:
        return None
    from lod.full.reps import build_rep

    fps = list(fps) if fps is not None else [30] * len(characters)
    clips = list(clips) if clips is not None else [None] * len(characters)
    reps = []
    for ch, n, f, c in zip(characters, names, fps, clips):
        if getattr(ch, "kind", None) not in ("skinned", "keyframed"):
            reps.append(None)  # scenery: never drawn far
            continue
        full = build_rep(ch, float(f))
        reps.append(build_far_rep(full, n, clips=_clip_indices(full, c)))
    return FarSplit(reps, float(far_pixels))


def subset(state, idx: np.ndarray):
    """A ``CrowdState`` of the rows ``idx`` of ``state`` (copies), for a selector that takes no agent list."""
    return type(state)(**{k: v[idx] for k, v in state.arrays().items()})


def merge(dl, n_agents: int, near, far_batches, remap: bool) -> None:
    """Add the far batches to the DrawList a mode selected for the ``near`` agents (None: all of them): with
    ``remap`` its instance ids (rows of a :func:`subset`) become the state's; ``stats`` count the far agents
    as instances (``"far"``: how many) and the rest as culled."""
    if remap and near is not None:
        for b in dl.batches:
            ids = np.asarray(b.instance_ids)
            if ids.size:
                b.instance_ids = np.where(ids >= 0, near[np.maximum(ids, 0)], ids).astype(np.int32)
    n_far = int(sum(b.n_instances for b in far_batches))
    dl.batches.extend(far_batches)
    if near is not None:
        dl.stats["instances"] = int(dl.stats.get("instances", 0)) + n_far
        dl.stats["culled"] = int(n_agents - dl.stats["instances"])
    dl.stats["far"] = n_far
    dl.stats["points"] = int(dl.stats.get("points", 0)) + n_far
