"""Declarative parameter schemas for effects (systems) and their validation.

Each effect module exposes ``PARAMS: dict[str, Param]``; the scene loader
validates a scene's effect table against it before anything is built.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any


class ParamError(ValueError):
    """A parameter value that its schema rejects; ``key`` names the parameter."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key = key
        self.message = message


_MISSING = object()


@dataclass(frozen=True)
class Param:
    """One parameter: type, default (``_MISSING`` = required), bounds, choices, doc.

    kind : "float" | "int" | "bool" | "str" | "vec2" | "vec3" | "list" | "table"
    """

    kind: str
    default: Any = _MISSING
    min: float | None = None
    max: float | None = None
    choices: tuple | None = None
    doc: str = ""

    @property
    def required(self) -> bool:
        return self.default is _MISSING

    def describe(self) -> str:
        parts = [self.kind]
        if self.min is not None:
            parts.append(f">= {self.min}")
        if self.max is not None:
            parts.append(f"<= {self.max}")
        if self.choices:
            parts.append("one of " + ", ".join(map(repr, self.choices)))
        return " ".join(parts)

    def check(self, key: str, value: Any) -> Any:
        """Return the value converted to its kind, or raise ParamError."""
        k = self.kind
        if k == "bool":
            if not isinstance(value, bool):
                raise ParamError(key, f"expected true or false, got {value!r}")
            return value
        if k in ("float", "int"):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParamError(key, f"expected a number ({self.describe()}), got {value!r}")
            if k == "int" and not float(value).is_integer():
                raise ParamError(key, f"expected an integer, got {value!r}")
            import math

            if not math.isfinite(float(value)):
                raise ParamError(key, f"expected a finite number, got {value!r}")
            v = int(value) if k == "int" else float(value)
            if self.min is not None and v < self.min:
                raise ParamError(key, f"expected >= {self.min}, got {value!r}")
            if self.max is not None and v > self.max:
                raise ParamError(key, f"expected <= {self.max}, got {value!r}")
            return v
        if k == "str":
            if not isinstance(value, str):
                raise ParamError(key, f"expected a string, got {value!r}")
            if self.choices and value not in self.choices:
                raise ParamError(key, f"expected one of {', '.join(map(repr, self.choices))}, got {value!r}")
            return value
        if k in ("vec2", "vec3"):
            n = 2 if k == "vec2" else 3
            import math

            if (not isinstance(value, (list, tuple)) or len(value) != n
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value)):
                raise ParamError(key, f"expected a list of {n} finite numbers, got {value!r}")
            return [float(x) for x in value]
        if k == "list":
            if not isinstance(value, list):
                raise ParamError(key, f"expected a list, got {value!r}")
            return value
        if k == "table":
            if not isinstance(value, dict):
                raise ParamError(key, f"expected a table, got {value!r}")
            return value
        raise ParamError(key, f"unknown parameter kind {k!r}")


def validate(schema: dict, table: dict, where: str) -> dict:
    """Check ``table`` against ``schema``; fill defaults. Unknown keys are errors.

    ``where`` prefixes the key in errors (e.g. ``effects[2]``).
    """
    out = {}
    for key in table:
        if key not in schema:
            raise ParamError(f"{where}.{key}", f"unknown key; accepted: {', '.join(sorted(schema)) or 'none'}")
    for key, p in schema.items():
        if key in table:
            out[key] = p.check(f"{where}.{key}", table[key])
        elif p.required:
            raise ParamError(f"{where}.{key}", f"required ({p.describe()})")
        else:
            out[key] = p.default
    return out
