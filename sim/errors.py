"""Errors the sim layer raises for bad assets or parameters.

The app (``crowd``) turns them into one-sentence messages and exit code 2.
"""
from __future__ import annotations


class AssetError(ValueError):
    """A broken or unsupported asset. The message names the file and what is wrong."""


def asset_label(character) -> str:
    """How a message names a character: its source file's name (a glTF file), else ``character 'NAME'``."""
    from pathlib import Path

    src = str(getattr(character, "source", "") or "")
    return Path(src).name if src else f"character {getattr(character, 'name', 'character')!r}"


def require_float32(character, what: str, values):
    """``values`` unchanged when every one is finite within the float32 range (what the GPU gets); otherwise
    :class:`AssetError`: one sentence naming the character's file and ``what`` (e.g. an animation that scales a
    joint to 1e38 skins its mesh beyond float32, which no representation can draw)."""
    import numpy as np

    a = np.asarray(values)
    if not (np.isfinite(a).all() and (a.size == 0 or float(np.abs(a).max()) <= float(np.finfo(np.float32).max))):
        raise AssetError(f"{asset_label(character)}: {what} are NaN or beyond the float32 range; expected an "
                         "animation that keeps the mesh finite")
    return values
