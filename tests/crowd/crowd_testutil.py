"""Helpers for the crowd tests: a tiny valid scene and running the CLI as a subprocess.

Imported by module name, so this file name must stay unique under tests/.
"""
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

TINY_SCENE = """\
name = "tiny"
seed = 1
dt = 0.05
frames = 3
effects = EFFECTS

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "grid"
character = "walker"
rows = 2
cols = 2
spacing = [1.5, 1.5]

[camera]
position = [1.0, 2.0, 7.0]
target = [1.0, 0.8, 1.0]

[render]
size = [64, 48]
png_every = 1

[lod]
mode = "none"
"""


def tiny_scene(effects='["animation"]', replace=None, append="") -> str:
    """TINY_SCENE with ``effects``, line replacements {old line: new line} and appended text."""
    text = TINY_SCENE.replace("EFFECTS", effects)
    for old, new in (replace or {}).items():
        assert old in text, old
        text = text.replace(old, new)
    return text + append


def run_cli(*args, cwd=None, timeout=300):
    """``python -m crowd ARGS`` in a subprocess; returns CompletedProcess (text)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run([sys.executable, "-m", "crowd", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd or REPO, env=env, timeout=timeout)


def run_python(code: str, *args, timeout=300):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True,
                          cwd=REPO, env=env, timeout=timeout)


