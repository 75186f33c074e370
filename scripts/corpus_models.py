"""Write the generated corpus: one glTF model per class of real-world character issue 20 names.

The models are those the tests build (``tests/fixtures/awkward_gltf.py`` writes the glTF JSON and binary itself;
the others go through the project's writer, ``sim.gltf.write.save_glb``): a mixed rig (two skins, rigid parts on
animated joints, weights summing to 1.8), a statue without animation, a joint chain 100 deep, 64 primitives in one
mesh, clips of 0.1 s and 60 s, a skinned mesh with animated morph targets, a skinned humanoid and a morph-target
(keyframed) quadruped, and two files no representation can draw (an animation beyond float32, lines only), which
must be refused, not fail. ``scripts/corpus.py ../shared/assets DIR`` then checks them all.

Run:  .venv/bin/python scripts/corpus_models.py DIR
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / "tests" / "fixtures"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


def write_models(out) -> list:
    """Write the generated corpus into ``out`` (created); returns the paths."""
    import awkward_gltf as ag
    from tiny_characters import tiny_morphed

    from lod.points.mode import keyframed_character
    from sim.gltf.write import save_glb
    from sim.procedural import humanoid, quadruped

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [ag.mixed_rig(out / "mixed_rig.glb"), ag.statue(out / "statue.glb"),
             ag.deep_chain(out / "chain_100.glb"), ag.many_primitives(out / "primitives_64.glb"),
             ag.clip_of(out / "clip_0.1s.glb", 0.1), ag.clip_of(out / "clip_60s.glb", 60.0),
             ag.exploding(out / "refused_exploding.glb"), ag.lines_only(out / "refused_lines.glb")]
    for name, ch in (("skin_morph.glb", tiny_morphed()), ("humanoid.glb", humanoid(2000, seed=5)),
                     ("keyframed_quadruped.glb", keyframed_character(quadruped(1500, seed=2), 6))):
        save_glb(ch, out / name)
        paths.append(out / name)
    return [Path(p) for p in paths]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: scripts/corpus_models.py DIR", file=sys.stderr)
        return 2
    out = Path(argv[0])
    if out.exists() and not out.is_dir():
        print(f"{out}: exists and is not a folder; give a folder to write the models into", file=sys.stderr)
        return 2
    try:
        paths = write_models(out)
    except OSError as e:
        print(f"{out}: cannot write the models there ({e.strerror})", file=sys.stderr)
        return 2
    for p in paths:
        print(p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
