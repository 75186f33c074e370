"""``[[characters]] variation``: the per-agent colour variation keys of a scene file (lod/variation.py makes the
words, render/tint.py applies them).

Parsed by :func:`parse_variation` for :mod:`crowd.scene`; an invalid value is reported through the parser's
``fail(key, message)`` as one line naming the key.
"""
from __future__ import annotations

import re

from sim.params import Param, validate

#: keys of ``[[characters]] variation`` (lod/variation.py): per-agent hue/saturation/value shifts, or a palette
VARIATION_SCHEMA = {
    "hue": Param("float", 0.0, min=0.0, max=0.5, doc="largest hue shift, turns (each agent: uniform in +-hue)"),
    "saturation": Param("float", 0.0, min=0.0, max=0.95, doc="largest relative saturation change"),
    "value": Param("float", 0.0, min=0.0, max=0.95, doc="largest relative value (brightness) change"),
    "palette": Param("list", None, doc="[[r, g, b], ...] in [0, 1]: each agent takes one, instead of the shifts"),
    "regions": Param("list", None, doc="named regions that vary (generated humanoid: skin, hair, shirt, trousers, "
                     "shoes; glTF: material:N); default: shirt and trousers of a humanoid, the whole mesh otherwise"),
}
#: the variation of a generated humanoid that sets none (``variation = false`` turns it off)
DEFAULT_VARIATION = {"hue": 0.15, "saturation": 0.3, "value": 0.25, "regions": ("shirt", "trousers")}


def parse_variation(v, where: str, generator: str | None, fail):
    """The validated ``variation`` of a character as ((key, value), ...), or None (none)."""
    if v is None:
        return tuple(DEFAULT_VARIATION.items()) if generator == "humanoid" else None
    if v is False:
        return None
    if v is True:  # the default amounts, on any character
        v = {k: x for k, x in DEFAULT_VARIATION.items() if k != "regions"}
    if not isinstance(v, dict):
        fail(where, f"expected a table {{ hue = 0.15, value = 0.25, ... }}, true or false, got {v!r}")
    c = validate(VARIATION_SCHEMA, v, where)
    pal = c["palette"]
    if pal is not None:
        def rgb(p):
            return isinstance(p, list) and len(p) == 3 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and 0.0 <= x <= 1.0 for x in p)

        if not pal or not all(rgb(p) for p in pal):
            fail(f"{where}.palette", f"expected a non-empty list of [r, g, b] in [0, 1], got {pal!r}")
        c["palette"] = tuple(tuple(float(x) for x in p) for p in pal)
    if c["regions"] is not None:
        from sim.procedural import HUMANOID_REGIONS

        if generator == "quadruped":
            fail(f"{where}.regions", "a generated quadruped has no named regions; leave it out to vary "
                      "the whole mesh")
        if generator == "humanoid":
            ok, accepted = (lambda r: r in HUMANOID_REGIONS), ", ".join(HUMANOID_REGIONS)
        else:  # a glTF model: its materials (checked against the file when the character is built)
            ok, accepted = (lambda r: isinstance(r, str) and re.fullmatch(r"material:\d+", r)), "\"material:N\""
        if not c["regions"] or not all(isinstance(r, str) and ok(r) for r in c["regions"]):
            fail(f"{where}.regions", f"expected a non-empty list of {accepted}, got {c['regions']!r}")
        c["regions"] = tuple(c["regions"])
    elif generator == "humanoid":
        c["regions"] = DEFAULT_VARIATION["regions"]
    return tuple(c.items())
