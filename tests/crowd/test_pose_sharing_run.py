"""``[lod] pose_rate`` through the engine (issue 29): every frame's copies get pose slots, frames.csv counts the
poses and the posed vertices, and exact times (``pose_rate = 0``) give every copy its own pose."""
import csv

import numpy as np
import pytest

from crowd.engine import Engine
from crowd.scene import load_scene
from crowd_testutil import tiny_scene


@pytest.mark.parametrize("rate, shared", [("0", False), ('"key"', True)])
def test_pose_rate_reaches_the_frames(tmp_path, write_scene, rate, shared):
    text = tiny_scene(replace={'mode = "none"': f'mode = "none"\npose_rate = {rate}',
                               "rows = 2": 'rows = 2\nphase = "zero"'}, append="")
    with Engine(load_scene(write_scene(text)), quiet=True) as e:
        res = e.run(out_dir=tmp_path / "out", png_every=0)
        dl = e.select(e.camera_at(e.world.time), e.scene.render.size)
    rows = list(csv.DictReader((res.out_dir / "frames.csv").open()))
    V = e.reps[0].positions.shape[0]
    for row in rows:
        poses = int(float(row["poses"]))
        assert poses == (1 if shared else 4)  # four copies in step: one pose when shared
        assert int(float(row["posed_vertices"])) == poses * V and float(row["pose_ms"]) >= 0.0
    slots = np.concatenate([b.instance_data[:, 13] for b in dl.batches if b.rep == "none:walker"])
    assert sorted(slots.tolist()) == ([0.0] * 4 if shared else [0.0, 1.0, 2.0, 3.0])
    assert dl.poses.rate == (0.0 if not shared else "key")
