"""The reference's cost, paid once: each reference frame (:mod:`crowd.reference`) cached by content.

A reference frame depends on the scene as loaded (every value, and the bytes of every file it names: characters,
camera path, floor plans), the frame's index, K, the size, and the code that simulates and draws it. Its cache
entry is named by the sha256 of all of these (:func:`frame_key`; the code as the digest of the sources of
``crowd``, ``sim``, ``lod`` and ``render``, shaders included, :func:`source_digest`), in the hierarchies' cache
folder (``$CROWD_CACHE_DIR`` or ``~/.cache/crowd``) under ``reference/``: ``<key>.png`` and ``<key>.json`` (the
seconds the frame took to draw, K, size, tiles), each written atomically, the JSON last; an entry is used only
when both are there and read back. A second report of the same scene draws nothing (:func:`reference_task`).
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
from pathlib import Path

#: format of an entry; changing what an entry holds or how a frame is drawn bumps it
REFERENCE_FORMAT = "reference-frame/1"
#: sub-folder of the cache folder
REFERENCE_DIR = "reference"
#: packages whose sources a reference frame depends on
SOURCE_PACKAGES = ("crowd", "sim", "lod", "render")
#: source files of those packages that go into :func:`source_digest` (Python and shaders)
SOURCE_SUFFIXES = (".py", ".glsl", ".vert", ".frag", ".geom", ".comp")


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """sha256 hex of the sources (relative path and bytes) of :data:`SOURCE_PACKAGES`."""
    import importlib

    h = hashlib.sha256()
    for pkg in SOURCE_PACKAGES:
        root = Path(importlib.import_module(pkg).__file__).parent
        for p in sorted(root.rglob("*")):
            if p.is_file() and p.suffix in SOURCE_SUFFIXES and "__pycache__" not in p.parts:
                h.update(f"{pkg}/{p.relative_to(root).as_posix()}\0".encode())
                h.update(p.read_bytes())
    return h.hexdigest()


def _files(obj, out: set) -> None:
    """Every existing file a scene names (Path or absolute path string, anywhere in its dataclasses)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            _files(getattr(obj, f.name), out)
    elif isinstance(obj, dict):
        for v in obj.values():
            _files(v, out)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            _files(v, out)
    elif isinstance(obj, (str, Path)):
        p = Path(obj)
        if p.is_absolute() and len(str(obj)) < 4096 and p.is_file():
            out.add(p)


def reference_identity(scene) -> str:
    """Every value of ``scene`` a frame's drawing depends on, as text: its outputs, frame count and measurements
    left out (they do not change a frame)."""
    norm = dataclasses.replace(scene, output_dir=Path("/"), frames=0, video=False, trajectories=False,
                               measurements=(), render=dataclasses.replace(scene.render, png_every=0))
    return repr(norm)


def scene_digest(scene) -> str:
    """sha256 hex of what a reference frame of ``scene`` depends on in the scene: :func:`reference_identity`
    and the bytes of every file it names."""
    h = hashlib.sha256(reference_identity(scene).encode())
    files: set = set()
    _files(scene, files)
    files.discard(Path(scene.path))  # its values are in the repr; a comment changes no frame
    for p in sorted(files):
        h.update(f"\0{p}\0".encode())
        h.update(hashlib.sha256(p.read_bytes()).digest())
    return h.hexdigest()


def frame_key(scene, k: int, frame: int, digest: str | None = None) -> str:
    """sha256 hex naming the cache entry of reference frame ``frame`` of ``scene`` at K = ``k`` (``digest``: its
    :func:`scene_digest`, when already computed)."""
    parts = [REFERENCE_FORMAT, source_digest(), digest or scene_digest(scene), f"{int(k)}",
             f"{int(scene.render.size[0])}x{int(scene.render.size[1])}", f"{int(frame)}"]
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()


def cache_folder() -> Path:
    from crowd.build import cache_dir

    return cache_dir() / REFERENCE_DIR


def load_frame(key: str):
    """(PNG bytes, entry dict) of a cached frame, or None when the entry is missing or unreadable."""
    from crowd.images import read_png

    d = cache_folder()
    png, meta = d / f"{key}.png", d / f"{key}.json"
    try:
        entry = json.loads(meta.read_text(encoding="utf-8"))
        data = png.read_bytes()
        import io

        read_png(io.BytesIO(data))
    except (OSError, ValueError):
        return None
    return data, entry


def store_frame(key: str, image, entry: dict) -> bytes:
    """Write a frame's entry (PNG then JSON, each atomically); returns the PNG bytes."""
    from crowd.images import write_png
    from sim.atomic_io import write_atomic

    d = cache_folder()
    d.mkdir(parents=True, exist_ok=True)
    p = write_png(d / f"{key}.png", image)
    write_atomic(d / f"{key}.json", json.dumps(entry, sort_keys=True))
    return Path(p).read_bytes()


def reference_task(scene, frames, k: int) -> dict:
    """The reference frames ``frames`` of ``scene`` at K = ``k``, from the cache or drawn (and cached): the unit
    of work of a report's reference, in this process or on a dask worker.

    Returns
    -------
    dict
        ``files`` (``frames/frame_NNNNN.png`` -> PNG bytes, as :func:`crowd.report.runs.run_task`), ``seconds``
        (frame -> seconds its drawing took, when drawn or when it was cached), ``cached`` (frames found in the
        cache), ``drawn`` (frames drawn now), ``tiles`` and ``tile_pixels`` (of the drawing, when any), ``host``,
        ``start``, ``end``; or ``{"error": message, "exit_code": code}`` for bad input (as ``run_task``).
    """
    import socket
    import time

    from crowd.errors import user_errors
    from crowd.reference import reference_frames

    start = time.time()
    try:
        digest = scene_digest(scene)
        keys = {int(f): frame_key(scene, k, f, digest) for f in frames}
        files, seconds, cached = {}, {}, []
        for f, key in sorted(keys.items()):
            hit = load_frame(key)
            if hit is not None:
                files[f"frames/frame_{f:05d}.png"] = hit[0]
                seconds[f] = float(hit[1].get("seconds", 0.0))
                cached.append(f)
        missing = sorted(set(keys) - set(cached))
        tiles = tile_pixels = None
        if missing:
            def keep(f, img, secs):
                seconds[f] = secs
                files[f"frames/frame_{f:05d}.png"] = store_frame(
                    keys[f], img, {"seconds": secs, "k": int(k), "frame": f, "size": list(scene.render.size)})

            plan = reference_frames(scene, missing, k, on_frame=keep)["plan"]
            tiles, tile_pixels = len(plan.origins), list(plan.tile_pixels)
    except user_errors() as e:
        return {"error": str(e).splitlines()[0] if str(e) else type(e).__name__,
                "exit_code": int(getattr(e, "exit_code", 2))}
    return {"files": files, "seconds": seconds, "cached": cached, "drawn": missing, "tiles": tiles,
            "tile_pixels": tile_pixels, "host": socket.gethostname(), "start": start, "end": time.time()}
