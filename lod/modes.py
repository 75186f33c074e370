"""Registry of LOD modes: what ``[lod] mode`` may name and how each is built.

A mode is a module exposing

    PARAMS : dict[str, sim.params.Param]
        Its keys in the scene's ``[lod]`` table (besides ``mode``), with
        defaults, e.g. ``poe`` for clusters or ``splat_size`` for points.
    build(characters, names, fps, params, static_reps=(), progress=None) -> (reps, selector)
        characters : list of sim.character.Character (index = CrowdState.character)
        names : list of str, the scene's character names (for representation keys)
        fps : list of int, the bake rate per character
        params : dict, the validated ``[lod]`` table
        static_reps : lod.full.reps.StaticRep scenery (terrain) the selector may be
            asked to draw through ``statics``
        progress : a callable ``progress(iterable, description)`` wrapping a
            long loop in a progress bar; False for no progress output at all
            (``--quiet``); None lets the mode decide (bars on a terminal)
        reps : list of representations to upload to the renderer
        selector : object with ``select(state, camera, size, statics=()) -> DrawList``

    A mode whose ``build`` also names a keyword parameter ``instancing`` is
    given the simulation's ``sim.instancing.Instancing`` (its groups of
    hierarchical instances, Wand & Strasser §3.6), or None when the scene has
    no instancing effect.

Modules are imported only when a scene asks for their mode, so an unused
representation costs nothing.
"""
from __future__ import annotations

import importlib

#: mode name -> module path (see the module docstring for the protocol)
MODES: dict[str, str] = {
    "none": "lod.full.mode",
    "points": "lod.points.mode",
    "clusters": "lod.clusters.mode",
    "triangles": "lod.chains.mode",
    "auto": "lod.auto.build",
}


def mode_names() -> tuple:
    return tuple(MODES)


def mode_module(mode: str):
    """Import and return the module of LOD ``mode`` (KeyError for an unknown mode)."""
    return importlib.import_module(MODES[mode])


def mode_params(mode: str) -> dict:
    """The ``[lod]`` parameters of ``mode`` (its PARAMS, or none)."""
    return dict(getattr(mode_module(mode), "PARAMS", {}))
