"""Atomic file writes: a file appears complete or not at all.

Every cache entry and output of the sandbox (hierarchies, camera paths, cost
models, PNG frames, telemetry) is written through :func:`atomic_open`: the
data goes to a temporary file in the destination's folder, which is moved into
place with ``os.replace`` (atomic on POSIX and Windows within one file
system) only when the writer finished without an exception. A crash, a full
disk or Ctrl-C leaves the previous file (or none), never a truncated one.

This module lives in ``sim``, the lowest layer, so that every package above
it (``sim``'s own caches such as ``sim.routing.cache``, ``lod``, ``render``,
``crowd``) and the scripts write through it; it imports nothing of the project.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb", encoding: str | None = None):
    """Open a temporary file beside ``path`` for writing; on a clean exit move it to ``path``.

    Parameters
    ----------
    path : destination file; its parent folders are created.
    mode : ``"wb"`` (binary) or ``"w"`` (text, ``encoding`` default utf-8).

    Yields
    ------
    file object; the destination is replaced only when the ``with`` block
    exits without an exception, else the temporary file is removed.
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_open {path}: mode must be 'wb' or 'w', got {mode!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        if mode == "w":
            f = os.fdopen(fd, "w", encoding=encoding or "utf-8")
        else:
            f = os.fdopen(fd, "wb")
        with f:
            yield f
            f.flush()
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600: give the file the usual permissions
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_atomic(path: str | os.PathLike, data: bytes | str) -> Path:
    """Write ``data`` (bytes, or str as UTF-8) to ``path`` atomically; returns the path."""
    with atomic_open(path, "wb") as f:
        f.write(data.encode("utf-8") if isinstance(data, str) else data)
    return Path(path)
