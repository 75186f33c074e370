"""``crowd report`` sweeps and settings: ``--sweep KEY=V1,V2`` arguments and the validated settings of a scene.

A setting is one combination of swept values (the cartesian product of the ``--sweep`` lists) applied to one
scene. Sweep keys are applied to the parsed TOML document *before* validation, so a swept value is checked
exactly as if it were written in the scene file.
"""
from __future__ import annotations

import copy
import itertools
import tomllib
from dataclasses import dataclass
from pathlib import Path

from crowd.errors import CrowdError, SceneError

#: swept keys besides ``lod.<key>`` (any key of an LOD mode's PARAMS, and ``lod.mode``)
SIZE_KEYS = ("render.size", "resolution")
#: swept ``[render]`` keys of the light and shadows (render.shadows: what each shadow setting costs)
RENDER_KEYS = ("render.shadows", "render.shadow_map_size", "render.shadow_distance")


class SweepError(CrowdError):
    """A bad ``--sweep`` argument (exit code 2)."""


def _common_lod_keys() -> tuple:
    """``[lod]`` keys valid for every mode (``lod.temporal.selection.LOD_COMMON_PARAMS``: keyframe_every, ...)."""
    try:
        from lod.temporal.selection import LOD_COMMON_PARAMS
    except ImportError:
        return ()
    return tuple(LOD_COMMON_PARAMS)


def _all_lod_keys() -> dict:
    """lod key -> modes accepting it (``mode`` and the common keys are accepted by all)."""
    from lod.modes import mode_names, mode_params

    out = {"mode": list(mode_names())}
    for m in mode_names():
        for k in mode_params(m):
            out.setdefault(k, []).append(m)
    for k in _common_lod_keys():
        out[k] = list(mode_names())
    return out


def parse_sweep(text: str) -> tuple:
    """``KEY=V1,V2,...`` -> (canonical key, [values]).

    Values are TOML literals when they parse as one (``0.5``, ``2``, ``true``),
    else strings (``points``); sizes are ``WxH``. The key is checked here; the
    values are checked by scene validation (:func:`expand_settings`).

    Raises
    ------
    SweepError
        Malformed argument or unknown key (one sentence naming what is accepted).
    """
    from crowd.scene import parse_size

    lod_keys = _all_lod_keys()
    accepted = ", ".join([f"lod.{k}" for k in lod_keys] + list(SIZE_KEYS) + list(RENDER_KEYS))
    key, sep, rest = text.partition("=")
    key = key.strip()
    if not sep or not key or not rest.strip():
        raise SweepError(f"--sweep {text!r}: expected KEY=V1,V2,... with KEY one of {accepted}")
    raw = [v.strip() for v in rest.split(",")]
    if any(not v for v in raw):
        raise SweepError(f"--sweep {text!r}: empty value in the list; expected KEY=V1,V2,...")
    if key in SIZE_KEYS:
        values = []
        for v in raw:
            s = parse_size(v)
            if s is None:
                from crowd.scene import SIZE_RANGE

                raise SweepError(f"--sweep {key}: bad size {v!r}; expected WxH with integers in "
                                 f"{SIZE_RANGE[0]} ..= {SIZE_RANGE[1]} (e.g. 640x360)")
            values.append(list(s))
        return "render.size", values
    if key not in RENDER_KEYS and (not key.startswith("lod.") or key[4:] not in lod_keys):
        raise SweepError(f"--sweep: unknown key {key!r}; accepted: {accepted}")
    values = []
    for v in raw:
        try:
            values.append(tomllib.loads(f"v = {v}")["v"])
        except tomllib.TOMLDecodeError:
            values.append(v)
    if len(set(map(repr, values))) != len(values):
        raise SweepError(f"--sweep {key}: a value is repeated in {rest!r}")
    return key, values


@dataclass
class Setting:
    """One combination of swept values for one scene.

    label : str, e.g. ``lod.mode=points, lod.splat_size=2`` (``scene`` when nothing is swept)
    values : dict canonical key -> value actually applied
    scene : crowd.scene.Scene, validated with the values applied
    """

    label: str
    values: dict
    scene: object
    slug: str = ""


def _fmt_value(v) -> str:
    if isinstance(v, list) and len(v) == 2:
        return f"{v[0]}x{v[1]}"
    return str(v)


def expand_settings(scene_path, sweeps: list, size: tuple | None = None, frames: int | None = None) -> list:
    """Validated settings of one scene: the cartesian product of ``sweeps``.

    Parameters
    ----------
    scene_path : path of a TOML scene file
    sweeps : list of (key, values) from :func:`parse_sweep`
    size : (w, h) or None, the ``--size`` override (a swept render.size wins)
    frames : int or None, the ``--frames`` override

    An ``lod.<key>`` that the combination's LOD mode does not accept is left
    out of that combination (so ``lod.mode=none,clusters`` sweeps with
    ``lod.poe=0.5,2`` give three settings), as are the scene's own ``[lod]``
    keys another mode does not accept. Duplicate combinations are merged.

    Raises
    ------
    crowd.errors.SceneError
        The scene file is invalid, or a swept value is not valid for its key.
    """
    from crowd.scene import load_scene, parse_scene
    from lod.modes import mode_params

    load_scene(scene_path)  # the file itself, with its own errors
    path = Path(scene_path)
    doc0 = tomllib.loads(path.read_text(encoding="utf-8"))
    if size is not None:
        doc0.setdefault("render", {})["size"] = list(size)
    keys = [k for k, _ in sweeps]
    settings, seen = [], set()
    for combo in itertools.product(*[vals for _, vals in sweeps]):
        doc = copy.deepcopy(doc0)
        lod = doc.setdefault("lod", {})
        if not isinstance(lod, dict):
            break  # load_scene above reported this
        applied = {}
        if "lod.mode" in keys:
            lod["mode"] = combo[keys.index("lod.mode")]
            applied["lod.mode"] = lod["mode"]
        mode = lod.get("mode", "none")
        try:
            accepted = set(mode_params(mode)) if isinstance(mode, str) else set()
        except KeyError:
            accepted = set()  # unknown mode: validation below names the accepted ones
        accepted |= set(_common_lod_keys())  # e.g. keyframe_every: every mode takes it
        if "lod.mode" in keys:
            for k in list(lod):
                if k != "mode" and k not in accepted:
                    del lod[k]
        for k, v in zip(keys, combo):
            if k == "lod.mode":
                continue
            if k == "render.size" or k in RENDER_KEYS:
                doc.setdefault("render", {})[k.split(".", 1)[1]] = v
            elif k[4:] in accepted:
                lod[k[4:]] = v
            else:
                continue
            applied[k] = v
        try:
            scene = parse_scene(doc, path)
        except SceneError as e:
            shown = ", ".join(f"{k}={_fmt_value(v)}" for k, v in applied.items())
            raise SceneError(e.path, e.key, str(e).split(": ", 2)[-1] + f" (with --sweep {shown})") from None
        ident = repr(sorted((k, repr(v)) for k, v in applied.items()))
        if ident in seen:
            continue
        seen.add(ident)
        if frames is not None:
            scene = scene.with_overrides(frames=frames)
        label = ", ".join(f"{k}={_fmt_value(v)}" for k, v in applied.items()) or "scene"
        settings.append(Setting(label=label, values=applied, scene=scene, slug=f"s{len(settings)}"))
    for k, _ in sweeps:
        if k.startswith("lod.") and k != "lod.mode" and not any(k in s.values for s in settings):
            raise SweepError(f"--sweep {k}: no swept LOD mode of {path} accepts {k[4:]!r}; "
                             f"sweep lod.mode too or set [lod] mode in the scene")
    return settings
