"""GLSL sources under ``render/shaders/``, loaded by name with a cache.

The files live in one folder per render family (``core/``: the instance, tint and lit shading every draw
shares, the HUD; ``poses/``: skinning, morph targets, the pose cache's pass and the skinned draws;
``points/``, ``raster/``, ``clusters/``, ``world/``); a file is named by its bare name (``"skinning.glsl"``)
wherever it lives, and a name may stand in one folder only.

A program named ``"skinned"`` is made of the stage files ``skinned.vert``
(required), ``skinned.frag`` or the shared ``lit.frag`` (fragment), and an
optional ``skinned.geom``. Sources may pull shared code in with a line
``#include "file.glsl"`` (resolved by name in the family folders, each file at
most once per program), which lets the draw and the transform-feedback capture
programs use the very same skinning code. A program may be compiled with
preprocessor ``defines`` (``#define NAME 1`` after the ``#version`` line), so
one file serves variants that ``#ifdef`` code in or out (e.g.
``MORPH_TARGETS``: the skinned shaders with morph targets, ``targets.glsl``)
and the variant without the define compiles none of that code.
"""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

#: folder holding the GLSL files, one subfolder per render family
SHADER_DIR = Path(__file__).resolve().parent / "shaders"
#: the family folders, in the order of ``render/__init__.py``
SHADER_FAMILIES = ("core", "poses", "points", "raster", "clusters", "world", "far")
#: file-name suffix of each stage, in moderngl's keyword names
STAGE_SUFFIX = {"vertex_shader": ".vert", "fragment_shader": ".frag", "geometry_shader": ".geom"}
#: fragment stage used when a program has no fragment file of its own
DEFAULT_FRAGMENT = "lit"

_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')


class ShaderNotFound(FileNotFoundError):
    """A shader stage or include file is missing."""


@lru_cache(maxsize=None)
def _index() -> dict:
    """Bare file name -> path over the family folders (a name in two folders is an error)."""
    out = {}
    for fam in SHADER_FAMILIES:
        for p in sorted((SHADER_DIR / fam).glob("*")):
            if p.is_file():
                if p.name in out:
                    raise ShaderNotFound(f"shader file {p.name} stands in two family folders: {out[p.name]} and {p}")
                out[p.name] = p
    return out


def shader_path(name: str) -> Path:
    """Path of the shader file ``name`` (its family folder; a missing file gives the path it would have
    at the top of ``SHADER_DIR``, for the message)."""
    return _index().get(name, SHADER_DIR / name)


def _read(path: Path) -> str:
    try:
        return path.read_text()
    except FileNotFoundError:
        raise ShaderNotFound(f"shader file {path} is missing") from None


def _expand(text: str, origin: str, seen: set) -> str:
    out = []
    for no, line in enumerate(text.splitlines(), 1):
        m = _INCLUDE.match(line)
        if not m:
            out.append(line)
            continue
        name = m.group(1)
        if name in seen:
            continue
        seen.add(name)
        path = shader_path(name)
        if not path.is_file():
            raise ShaderNotFound(f"{origin}:{no}: included shader file {path} is missing")
        out.append(f"// begin {name}")
        out.append(_expand(_read(path), name, seen))
        out.append(f"// end {name}")
    return "\n".join(out) + "\n"


@lru_cache(maxsize=None)
def load_source(filename: str) -> str:
    """Source text of one shader file with its includes expanded (cached)."""
    path = shader_path(filename)
    if not path.is_file():
        raise ShaderNotFound(f"shader file {path} is missing")
    return _expand(_read(path), filename, {filename})


@lru_cache(maxsize=None)
def _program_sources(name: str, fragment: bool) -> tuple:
    vert = shader_path(f"{name}.vert")
    if not vert.is_file():
        raise ShaderNotFound(f"shader program {name!r}: missing vertex stage file {vert}")
    src = {"vertex_shader": load_source(vert.name)}
    if fragment:
        frag = shader_path(f"{name}.frag")
        if not frag.is_file():
            frag = shader_path(f"{DEFAULT_FRAGMENT}.frag")
        if not frag.is_file():
            raise ShaderNotFound(f"shader program {name!r}: missing fragment stage file {frag}")
        src["fragment_shader"] = load_source(frag.name)
    geom = shader_path(f"{name}.geom")
    if geom.is_file():
        src["geometry_shader"] = load_source(geom.name)
    return tuple(src.items())


def with_defines(source: str, defines=()) -> str:
    """``source`` with ``#define NAME 1`` for every name in ``defines`` after its
    ``#version`` line (at the top when it has none)."""
    if not defines:
        return source
    for d in defines:
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", str(d)):
            raise ValueError(f"shader define {d!r}: expected a GLSL identifier")
    block = "".join(f"#define {d} 1\n" for d in defines)
    lines = source.splitlines(keepends=True)
    at = next((i + 1 for i, ln in enumerate(lines) if ln.lstrip().startswith("#version")), 0)
    return "".join(lines[:at]) + block + "".join(lines[at:])


def program_sources(name: str, fragment: bool = True, defines=()) -> dict:
    """Stage sources of program ``name`` as moderngl ``ctx.program`` keywords.

    ``fragment=False`` gives a vertex-only program (transform feedback);
    ``defines``: preprocessor names defined in every stage (:func:`with_defines`).
    """
    return {k: with_defines(v, tuple(defines)) for k, v in _program_sources(name, bool(fragment))}


def prog_name(kind: str, skinning: str = "palette") -> str:
    """Shader program drawing a representation kind."""
    if kind == "skinned" and skinning == "direct":
        return "skinned_direct"
    return kind
