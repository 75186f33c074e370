"""``crowd inspect`` (crowd/inspect.py): VDR-AM hierarchy views written as a PNG off screen."""
import numpy as np
import pytest
from PIL import Image

from crowd import inspect as ci
from crowd.cli import main

ASSET = "generator:humanoid:1500:3"


@pytest.fixture(scope="module")
def loaded():
    return ci.load(ASSET, quiet=True)


def test_inspect_data_covers_the_mesh(loaded):
    ch, h = loaded
    d = ci.inspect_data(ch, h, poe=1.0)
    assert d["leaf_triangles"].shape[0] == h.n_triangles
    assert d["leaf_colors"].shape == (h.n_leaves, 3)
    assert len({tuple(c) for c in d["leaf_colors"].tolist()}) == h.n_leaves  # distinct colours
    assert np.all(np.isfinite(d["positions"]))
    # the cut covers every leaf once, and a far camera selects a coarser cut than a near one
    leaves = np.concatenate([np.arange(h.leaf_lo[i], h.leaf_hi[i]) for i in d["cut"]])
    assert np.array_equal(np.sort(leaves), np.arange(h.n_leaves))
    far = ci.inspect_data(ch, h, poe=1.0, camera=(0.0, 1.0, 60.0))
    assert far["cut_triangles"].shape[0] < d["cut_triangles"].shape[0]
    assert ci.inspect_data(ch, h, poe=0.0)["cut_triangles"].shape[0] == h.n_triangles
    rep = ci.inspect_data(ch, h, pose=0)
    assert rep["pose_label"].startswith("representative pose 0")


def test_png_written_with_several_cluster_colours(tmp_path, capsys):
    out = tmp_path / "h.png"
    assert main(["inspect", ASSET, "--png", str(out), "--size", "600x300", "--time", "0.2"]) == 0
    img = np.asarray(Image.open(out).convert("RGB"))
    assert img.shape == (300, 600, 3)
    left = img[:, :200].reshape(-1, 3)  # the cluster view
    colours, counts = np.unique(left // 16, axis=0, return_counts=True)
    assert np.count_nonzero(counts > 20) >= 8, "the cluster view should show many distinct colours"
    assert not list(tmp_path.glob(".inspect-*"))  # no temp file left
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize("argv, words", [
    (["inspect", "generator:nosuchthing", "--png", "X"], "generator"),
    (["inspect", "/nonexistent/model.glb", "--png", "X"], "model.glb"),
    (["inspect", ASSET, "--png", "X", "--clip", "dance"], "dance"),
    (["inspect", ASSET, "--png", "X", "--pose", "999"], "--pose"),
    (["inspect", ASSET, "--png", "X.jpg"], ".png"),
])
def test_bad_input_is_one_sentence_and_exit_2(loaded, tmp_path, capsys, argv, words):
    """(``loaded``: the hierarchy is in this worker's cache, so no first build's progress bar precedes the line.)"""
    argv = [a.replace("X", str(tmp_path / "o.png")) if a == "X" else a for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())  # nothing written


def test_bad_camera_is_rejected_by_the_parser(capsys):
    with pytest.raises(SystemExit) as e:
        main(["inspect", ASSET, "--camera", "1,2"])
    assert e.value.code == 2


def test_window_without_display_is_one_sentence(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["inspect", ASSET]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--png" in err
