"""Atomic outputs: a run's directory appears complete or not at all.

A run writes into a temporary sibling directory ``.<name>.tmp-<pid>`` next to
the final one and renames it into place only when the run has finished,
replacing a previous run's directory. On an error or an interrupt the temporary
directory is removed, so no half-written output is ever left behind. A run
killed outright (SIGKILL, power loss) cannot clean up: the next run into the
same place removes the temporary siblings whose process is gone
(:func:`remove_stale_siblings`). Single files are written to a temporary file
in the same folder and ``os.replace``-d.
"""
from __future__ import annotations

import json
import os
import shutil
from contextlib import contextmanager
from pathlib import Path

from sim.atomic_io import write_atomic as _write_atomic


def temp_sibling(final: Path) -> Path:
    """``.<name>.tmp-<pid>`` beside ``final``."""
    return final.parent / f".{final.name}.tmp-{os.getpid()}"


def _alive(pid: int) -> bool:
    """True when a process ``pid`` exists (or may: one we may not signal counts as alive)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def remove_stale_siblings(final: Path) -> list:
    """Remove ``.<name>.tmp-<pid>`` / ``.<name>.old-<pid>`` folders beside ``final``
    left by runs whose process no longer exists; returns the removed paths.

    A run killed between its two renames (:func:`atomic_dir`) left no ``final``
    but the previous, complete output as ``.old-<pid>``: that one is moved back
    to ``final`` instead of removed. Only processes of this PID namespace are
    seen: a run writing to the same folder from another container counts as gone."""
    removed = []
    for kind in ("old", "tmp"):
        for p in sorted(final.parent.glob(f".{final.name}.{kind}-*")):
            pid = p.name.rsplit("-", 1)[-1]
            if p.is_dir() and pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
                if kind == "old" and not final.exists():
                    os.replace(p, final)
                    continue
                shutil.rmtree(p, ignore_errors=True)
                removed.append(p)
    return removed


def check_output_dir(final: str | os.PathLike) -> Path:
    """Fail early, before any work, when ``final`` cannot become the run's output directory.

    Returns the absolute path. Raises :class:`crowd.errors.CrowdError` when
    ``final`` is an existing non-directory, or when its nearest existing
    ancestor is not a writable directory.
    """
    from crowd.errors import CrowdError

    final = Path(final).absolute()
    if final.exists() and not final.is_dir():
        raise CrowdError(f"{final}: output path exists and is not a directory; give a directory (--out DIR)")
    parent = final.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise CrowdError(f"{final}: cannot create the output directory ({parent} is not a writable directory)")
    return final


@contextmanager
def atomic_dir(final: str | os.PathLike):
    """Yield a fresh temporary directory that becomes ``final`` on success.

    On normal exit the temporary directory replaces ``final`` (a previous
    directory of that name is removed first; the swap goes through a second
    temporary name so ``final`` is never a mix of two runs). On any exception,
    KeyboardInterrupt included, the temporary directory is deleted and the
    exception propagates; ``final`` is untouched.

    Parameters
    ----------
    final : path of the directory to produce

    Yields
    ------
    Path of the temporary directory to write into
    """
    final = Path(final).absolute()
    if final.exists() and not final.is_dir():
        raise FileExistsError(f"{final} exists and is not a directory")
    final.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_siblings(final)
    tmp = temp_sibling(final)
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = final.parent / f".{final.name}.old-{os.getpid()}"
    try:
        if final.exists():
            os.replace(final, old)
        os.replace(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        if old.exists() and not final.exists():
            os.replace(old, final)
        raise
    shutil.rmtree(old, ignore_errors=True)


def write_atomic(path: str | os.PathLike, data: bytes | str) -> None:
    """Write ``data`` to ``path`` via a temporary file in the same folder + ``os.replace``
    (:func:`sim.atomic_io.write_atomic`)."""
    _write_atomic(path, data)


def write_json(path: str | os.PathLike, obj, indent: int | None = 1) -> None:
    """``write_atomic`` of ``obj`` as JSON (indented unless ``indent`` is None; NaN/Inf are refused: not JSON)."""
    text = json.dumps(obj, indent=indent, allow_nan=False, separators=None if indent is not None else (",", ":"))
    write_atomic(path, text + "\n")
