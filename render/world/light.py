"""One directional light for every shader: direction, colour and ambient term.

The character shaders (``lit.frag`` for full detail, triangle chains and clusters; ``points_common.glsl`` for
point splats) and the world shaders (ground, props, obstacles) read the same uniforms, set by :func:`apply_light`:

- ``u_light_dir`` (vec3): unit direction *towards* the light, world space (Y up);
- ``u_light_color`` (vec3): linear RGB intensity of the direct light;
- ``u_ambient`` (float): ambient factor.

``u_sun`` is the older name of ``u_light_dir``; programs that still declare it get the same value.

The defaults reproduce the look the renderer had before the light was configurable (sun (0.35, 0.85, 0.4),
white, ambient 0.3), so frames of a scene without a ``[render] light_*`` key are unchanged.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

#: default direction towards the light (world, normalised at use)
DEFAULT_DIRECTION = (0.35, 0.85, 0.4)
#: default light colour (linear RGB)
DEFAULT_COLOR = (1.0, 1.0, 1.0)
#: default ambient factor
DEFAULT_AMBIENT = 0.3
#: accepted values of ``[render] shadows`` (drawn by render.shadows) and the default
SHADOW_MODES = ("blob", "map", "none")
DEFAULT_SHADOWS = "blob"
#: a direction shorter than this is refused (no usable normalisation)
MIN_LENGTH = 1e-6
#: largest light colour component / ambient accepted
MAX_INTENSITY = 16.0


class LightError(ValueError):
    """A bad light parameter: ``key`` and a one-sentence ``message`` (what is wrong, what is accepted)."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key, self.message = key, message


@dataclass(frozen=True)
class Light:
    """A directional light.

    direction : (3,) float, unit vector towards the light (world)
    color : (3,) float, linear RGB in [0, MAX_INTENSITY]
    ambient : float in [0, MAX_INTENSITY]
    """

    direction: tuple = tuple(v / math.sqrt(sum(x * x for x in DEFAULT_DIRECTION)) for v in DEFAULT_DIRECTION)
    color: tuple = DEFAULT_COLOR
    ambient: float = DEFAULT_AMBIENT


def make_light(direction=DEFAULT_DIRECTION, color=DEFAULT_COLOR, ambient=DEFAULT_AMBIENT) -> Light:
    """A validated :class:`Light`; ``direction`` is normalised.

    Raises
    ------
    LightError
        with ``key`` (``light_dir``, ``light_color``, ``ambient``) and ``message``, one sentence on what is wrong
        and what is accepted (a zero or non-finite direction, a negative or non-finite colour...).
    """
    d = _vec3("light_dir", direction)
    n = math.sqrt(sum(x * x for x in d))
    if not n > MIN_LENGTH:
        raise LightError("light_dir", f"expected a non-zero direction [x, y, z] towards the light, "
                         f"got {list(direction)!r}")
    c = _vec3("light_color", color)
    if not all(0.0 <= x <= MAX_INTENSITY for x in c):
        raise LightError("light_color", f"expected three numbers in [0, {MAX_INTENSITY:g}] (linear RGB), "
                         f"got {list(color)!r}")
    try:
        a = float(ambient)
    except (TypeError, ValueError):
        a = float("nan")
    if isinstance(ambient, bool) or not 0.0 <= a <= MAX_INTENSITY:
        raise LightError("ambient", f"expected a number in [0, {MAX_INTENSITY:g}], "
                         f"got {ambient!r}")
    return Light(direction=tuple(x / n for x in d), color=c, ambient=a)


def _vec3(key: str, v) -> tuple:
    try:
        ok = len(v) == 3 and not any(isinstance(x, bool) for x in v)
        out = tuple(float(x) for x in v) if ok else ()
    except (TypeError, ValueError):
        out = ()
    if len(out) != 3 or not all(math.isfinite(x) for x in out):
        raise LightError(key, f"expected three finite numbers [x, y, z], got {v!r}")
    return out


def apply_light(prog, light: Light | None = None) -> None:
    """Set the light uniforms a program declares (``u_light_dir`` / ``u_sun``, ``u_light_color``, ``u_ambient``)."""
    light = light or Light()
    for name in ("u_light_dir", "u_sun"):
        if name in prog:
            prog[name].value = tuple(light.direction)
    if "u_light_color" in prog:
        prog["u_light_color"].value = tuple(light.color)
    if "u_ambient" in prog:
        prog["u_ambient"].value = float(light.ambient)
