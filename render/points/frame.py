"""Per-frame CPU helper of the points drawer (``render/points/draw.py``):
the windows that keep every storage-buffer binding within the GL limit.

Storage-buffer limit: a GL implementation may refuse to address more than
``GL_MAX_SHADER_STORAGE_BLOCK_SIZE`` bytes through one binding (llvmpipe: 128 MB, i.e. the
instance data of 2 M instances, the job table of 8 M jobs, 16 M triangle-vertex items). A
frame above it is drawn in windows (:func:`instance_windows`): the jobs whose instances lie in
one range of instance rows, that range bound at its offset and the jobs' instance indices made
relative to it, at most ``max_jobs`` jobs a piece. The splat passes' atomics do not depend on
the order or grouping of the points, so a windowed frame has the same pixels (tested with a
small injected limit).
"""
from __future__ import annotations

import numpy as np


def instance_windows(jobs: np.ndarray, rows: int, window: int, max_jobs: int) -> list:
    """Cut a job table (J, >=3: column 2 the instance row, in ``0 .. rows - 1``) into pieces.

    Returns a list of (first row, piece): each piece holds the jobs of instance rows
    ``first .. first + window - 1`` (at most ``max_jobs``, in table order), their column 2 made
    relative to ``first``. One window (the table itself, first row 0) when ``rows <= window``
    and ``J <= max_jobs``.
    """
    j = np.asarray(jobs)
    window, max_jobs = max(1, int(window)), max(1, int(max_jobs))
    if rows <= window and j.shape[0] <= max_jobs:
        return [(0, j)] if j.shape[0] else []
    out = []
    w = j[:, 2].astype(np.int64) // window
    order = np.argsort(w, kind="stable")
    cuts = np.flatnonzero(np.diff(w[order])) + 1
    for part in np.split(order, cuts):
        if not part.shape[0]:
            continue
        first = int(w[part[0]]) * window
        piece = j[part].copy()
        piece[:, 2] -= first
        for a in range(0, piece.shape[0], max_jobs):
            out.append((first, piece[a:a + max_jobs]))
    return out
