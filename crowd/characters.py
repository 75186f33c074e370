"""Building the characters a scene or ``crowd info`` names.

A character comes from a procedural generator (``sim.procedural``) or a glTF
file (``sim.gltf.load``). The generator modules and the glTF importer are
imported only when a character needs them.
"""
from __future__ import annotations

import re
from pathlib import Path

from crowd.errors import AssetError
from crowd.scene import DEFAULT_TRIANGLES, GENERATORS, GLTF_SUFFIXES, CharacterSpec

_GEN_SPEC = re.compile(r"^generator:(?P<gen>[A-Za-z_]+)(?::(?P<tri>[^:]*))?(?::(?P<seed>[^:]*))?$")


def build_character(spec: CharacterSpec):
    """Build the :class:`sim.character.Character` of ``spec``.

    Generators get ``triangles`` and ``seed``; glTF files are loaded as they
    are (``scale`` is applied per agent through ``CrowdState.scale``, not to
    the mesh). Errors in a glTF file are ``sim.errors.AssetError`` naming it.
    """
    if spec.generator is not None:
        import sim.procedural

        gen = getattr(sim.procedural, spec.generator)
        ch = gen(triangles=spec.triangles, seed=spec.seed)
        if getattr(spec, "dance", 0.0):  # a long dance-like clip (sim.dance)
            from sim.dance import dance_clip

            ch.clips["dance"] = dance_clip(ch, float(spec.dance), seed=spec.seed)
    else:
        from sim.gltf.load import load_gltf

        ch = load_gltf(spec.file)
    if ch.kind == "skinned":
        from sim.skin_weights import repair_mesh_weights

        # a safety net for every source: weights that are negative, all zero or off 1 are repaired with a
        # warning naming the asset; NaN weights are refused in one sentence
        repair_mesh_weights(ch.mesh, str(spec.file or spec.generator), ch.skeleton.n_joints)
    ch.name = spec.name
    if spec.variation is not None:
        regions = dict(spec.variation).get("regions")
        missing = [r for r in regions or () if r not in getattr(ch, "regions", {})]
        if missing:
            have = ", ".join(sorted(getattr(ch, "regions", {}))) or "none"
            raise AssetError(f"{spec.file or spec.generator}: characters {spec.name!r}: variation.regions: "
                             f"{missing[0]!r} is not a region of this model; it has: {have}")
        set_variation_mask(ch, regions)
    return ch


def build_scene_character(scene_path, index: int, spec: CharacterSpec):
    """:func:`build_character` of a scene's ``characters[index]``; a file it cannot load is named with the scene
    and the key that pointed to it (``scene.toml: characters[0].file: /path/fox.glb: truncated GLB: ...``).

    Raises
    ------
    crowd.errors.SceneError
        The asset's own one-sentence error, behind the scene, key and the file's full path.
    """
    from sim.errors import AssetError as SimAssetError

    try:
        return build_character(spec)
    except (SimAssetError, AssetError) as e:
        raise scene_asset_error(scene_path, [spec], e, index) from None


def scene_asset_error(scene_path, specs, error, index: int | None = None):
    """A :class:`crowd.errors.SceneError` of ``error`` (an asset's one-sentence error) naming the scene, the key
    of the character it is about (``index``, or the one of ``specs`` whose file the message names) and the
    file's full path; ``error`` itself when no character's file is named."""
    from crowd.errors import SceneError

    msg = str(error).splitlines()[0] if str(error) else type(error).__name__
    for i, spec in enumerate(specs):
        if spec.file is None:
            continue
        for head in (f"{spec.file}: ", f"{Path(spec.file).name}: "):
            if msg.startswith(head):
                return SceneError(scene_path, f"characters[{i if index is None else index}].file",
                                  f"{spec.file}: {msg[len(head):]}")
    if index is not None:
        spec = specs[0]
        key = f"characters[{index}]" + (".file" if spec.file is not None else "")
        return SceneError(scene_path, key, f"{spec.file}: {msg}" if spec.file is not None else msg)
    return error


def set_variation_mask(ch, regions=None) -> None:
    """Write the colour-variation mask into the alpha of the character's vertex
    colours (render/tint.py: 1 varies, 0 keeps its colour): 1 on the vertices of
    ``regions`` (names of ``ch.regions``), everywhere when ``regions`` is None.
    The alpha reaches every representation with the colours (chains, clusters,
    point samples), so every LOD mode varies the same parts."""
    import numpy as np

    meshes = [ch.mesh] if ch.kind == "skinned" else [k for a in ch.animations.values() for k in a.keyframes]
    for m in meshes:
        col = np.array(m.vertex_colors() if hasattr(m, "vertex_colors") else m.colors, np.float32, copy=True)
        if regions is None:
            col[:, 3] = 1.0
        else:
            sel = np.zeros(col.shape[0], bool)
            for r in regions:
                sel |= np.asarray(ch.regions[r], bool)
            col[:, 3] = sel.astype(np.float32)
        m.colors = col


def clip_names(character) -> list:
    """Clip names of a character in clip-index order."""
    return list(character.clip_names())


def clip_duration(character, index: int) -> float:
    """Duration in seconds of clip ``index`` of ``character``."""
    name = clip_names(character)[index]
    clips = character.clips if character.kind == "skinned" else character.animations
    return float(clips[name].duration)


def parse_asset(arg: str) -> CharacterSpec:
    """Turn a ``crowd info`` argument into a CharacterSpec.

    Accepts ``generator:NAME[:TRIANGLES[:SEED]]`` (e.g. ``generator:humanoid:5000``)
    or a path to a ``.glb`` / ``.gltf`` file.

    Raises
    ------
    crowd.errors.AssetError
        Unknown generator, bad numbers, missing file or unsupported suffix.
    """
    m = _GEN_SPEC.match(arg)
    if arg.startswith("generator:"):
        if not m or m["gen"] not in GENERATORS:
            raise AssetError(f"{arg}: expected generator:NAME[:TRIANGLES[:SEED]] with NAME one of "
                             + ", ".join(GENERATORS))
        tri, seed = DEFAULT_TRIANGLES, 0
        if m["tri"]:
            if not m["tri"].isdigit() or not 500 <= int(m["tri"]) <= 200000:
                raise AssetError(f"{arg}: triangles: expected an integer in 500 ..= 200000, got {m['tri']!r}")
            tri = int(m["tri"])
        if m["seed"]:
            if not m["seed"].isdigit():
                raise AssetError(f"{arg}: seed: expected an integer >= 0, got {m['seed']!r}")
            seed = int(m["seed"])
        return CharacterSpec(name=m["gen"], generator=m["gen"], file=None, triangles=tri, seed=seed, scale=1.0,
                             fps=30)
    path = Path(arg)
    if path.suffix.lower() not in GLTF_SUFFIXES:
        raise AssetError(f"{arg}: expected a glTF file ({', '.join(GLTF_SUFFIXES)}) or generator:NAME[:TRIANGLES], "
                         f"e.g. generator:humanoid:5000")
    if not path.is_file():
        raise AssetError(f"{arg}: file not found")
    return CharacterSpec(name=path.stem, generator=None, file=path.resolve(), triangles=None, seed=0, scale=1.0,
                         fps=30)
