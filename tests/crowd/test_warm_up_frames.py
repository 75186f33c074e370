"""A steady frame makes no GL object (issue 50, item 3): a draw that makes one is a warm-up frame, which mode auto's
fit, its plans' measurements and the frame budgets leave out (lod.drawlist.DrawList.warm_up); a drawer that made
one every frame would leave them nothing to learn from. Each single mode draws the tiny scene for 10 frames: the
first frame compiles and allocates, the frames after the third make nothing."""
import pytest
from crowd_testutil import tiny_scene

from crowd.engine import Engine
from crowd.scene import load_scene
from render.renderer import Renderer


@pytest.mark.parametrize("mode", ["none", "triangles", "clusters", "points"])
def test_steady_frames_make_no_gl_objects(tmp_path, monkeypatch, mode):
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    p = tmp_path / "tiny.toml"
    p.write_text(tiny_scene(replace={'mode = "none"': f'mode = "{mode}"', "frames = 3": "frames = 10"}))
    made, draw = [], Renderer.draw

    def counted(self, dl, *a, **k):
        out = draw(self, dl, *a, **k)
        made.append(int(dl.stats["gl_created"]))
        return out

    monkeypatch.setattr(Renderer, "draw", counted)
    with Engine(load_scene(p), quiet=True) as eng:
        eng.run(out_dir=tmp_path / "out")
    assert len(made) == 10 and made[0] > 0, made
    assert made[3:] == [0] * 7, made
