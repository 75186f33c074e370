"""Screen-door transitions (DrawBatch.fade, lod/temporal/selection.py): no fade
draws every fragment (bit-identical images), the outgoing and incoming patterns
are exact complements (their pixel coverage partitions the unfaded one), and
an instance drawn by both halves of a transition renders exactly the unfaded
image -- for skinned triangles, cluster cuts and point splats (both paths)."""
import dataclasses

import numpy as np
import pytest

from tiny_characters import tiny_skinned, uv_sphere

from lod.clusters import mode as clusters_mode
from lod.full import mode as nolod
from lod.full import reps as nolod_reps
from lod.points import mode as pm
from lod.points import rep as pm_rep
from lod.drawlist import FADE_IN, FADE_OUT, fade_uniform
from lod.view import Camera
from render.renderer import Renderer
from sim.character import KeyframedCharacter
from sim.keyframes import Keyframe, KeyframeAnimation, Segment
from sim.procedural import humanoid
from sim.state import CrowdState

W, H = 160, 120
BG = (0.0, 0.0, 0.0)


def ball_character(n_lat=30, n_lon=48) -> KeyframedCharacter:
    """A UV sphere (radius 1 at y = 1), one non-looping keyframe segment."""
    nrm, idx = uv_sphere(n_lat, n_lon)
    col = np.tile([0.8, 0.5, 0.2, 1.0], (nrm.shape[0], 1)).astype(np.float32)
    k0 = Keyframe((nrm + [0, 1, 0]).astype(np.float32), nrm.astype(np.float32), col, idx)
    k1 = Keyframe((1.1 * nrm + [0, 1, 0]).astype(np.float32), nrm.astype(np.float32), col, idx)
    ident = np.arange(nrm.shape[0], dtype=np.int32)
    anim = KeyframeAnimation("swell", np.array([0.0, 1.0]), [k0, k1], [Segment(ident, ident, idx.copy())],
                             duration=1.0, loop=False)
    return KeyframedCharacter("ball", {"swell": anim})


@pytest.fixture(scope="module")
def reps(tmp_path_factory):
    sk = nolod_reps.build_rep(tiny_skinned(), fps=30, key="none:tiny")
    creps, csel = clusters_mode.build([humanoid(1000, 2)], ["h"], [30], {"poe": 3.0}, cache=False)
    cache = pm_rep.HierarchyCache(tmp_path_factory.mktemp("pcache"))
    preps, psel = pm.build([ball_character()], ["ball"], [30], {"splat_size": 1}, cache=cache,
                           progress=lambda it, d: it)
    return {"skinned": ([sk], nolod.NoLodSelector([sk])), "clusters": (creps, csel), "points": (preps, psel)}


@pytest.fixture(scope="module")
def renderer(gl_ctx, reps):
    r = Renderer((W, H), ctx=gl_ctx, debug=True)
    for rs, _ in reps.values():
        for rep in rs:
            r.upload(rep)
    yield r
    r.release()


CAMS = {"skinned": Camera.look_at((1.0, 2.0, 7.0), (0.0, 1.5, 0.0), fov_y=50),
        "clusters": Camera.look_at((0.5, 1.2, 4.0), (0.0, 0.9, 0.0), fov_y=50),
        "points": Camera.look_at((0.0, 1.0, 9.0), (0.0, 1.0, 0.0), fov_y=50)}


def _dl(reps, kind):
    st = CrowdState.empty(2)
    st.position[1] = (0.8, 0.0, -1.5)  # two overlapping instances
    st.heading[1] = 1.0
    st.anim_time[:] = (0.2, 0.6)
    return reps[kind][1].select(st, CAMS[kind], (W, H))


def _faded(dl, *fades):
    """The DrawList with every batch drawn once per fade of ``fades``."""
    return dataclasses.replace(dl, batches=[dataclasses.replace(b, fade=f) for f in fades for b in dl.batches])


def _render(r, dl, path=None):
    if path is not None:
        r.drawer("points").path = path
    r.draw(dl, background=BG)
    return r.read_pixels().astype(np.int32)


def _fg(img):
    return img.max(axis=2) > 0


CASES = [("skinned", None), ("clusters", None), ("points", "compute"), ("points", "gl_points")]


@pytest.mark.parametrize("kind,path", CASES)
def test_no_fade_is_bit_identical(renderer, reps, kind, path):
    dl = _dl(reps, kind)
    assert all(b.fade is None for b in dl.batches)
    plain = _render(renderer, dl, path)
    assert _fg(plain).sum() > 300
    # t = 0 keeps the whole outgoing batch, t = 1 the whole incoming one: the same image, bit for bit
    assert np.array_equal(_render(renderer, _faded(dl, (0.0, FADE_OUT)), path), plain)
    assert np.array_equal(_render(renderer, _faded(dl, (1.0, FADE_IN)), path), plain)
    assert np.array_equal(_render(renderer, dl, path), plain)


@pytest.mark.parametrize("kind,path", CASES)
@pytest.mark.parametrize("t", [0.25, 0.5, 0.875])
def test_fades_are_complementary(renderer, reps, kind, path, t):
    dl = _dl(reps, kind)
    plain = _render(renderer, dl, path)
    out = _render(renderer, _faded(dl, (t, FADE_OUT)), path)
    inn = _render(renderer, _faded(dl, (t, FADE_IN)), path)
    fp, fo, fi = _fg(plain), _fg(out), _fg(inn)
    # the two halves' coverages partition the unfaded coverage ...
    assert not (fo & fi).any()
    assert np.array_equal(fo | fi, fp)
    # ... each the expected share of it (an 8x8 ordered pattern: within a few percent)
    assert fo.sum() / fp.sum() == pytest.approx(1.0 - t, abs=0.06)
    # and both halves of a transition in one frame draw the unfaded image exactly
    both = _render(renderer, _faded(dl, (t, FADE_OUT), (t, FADE_IN)), path)
    assert np.array_equal(both, plain)


def test_fade_can_fail(renderer, reps):
    """The complement check sees a wrong pattern: two outgoing halves leave holes."""
    dl = _dl(reps, "skinned")
    plain = _render(renderer, dl)
    two_out = _render(renderer, _faded(dl, (0.5, FADE_OUT), (0.5, FADE_OUT)))
    assert (_fg(plain) & ~_fg(two_out)).sum() > 0.3 * _fg(plain).sum()


def test_fade_uniform_values():
    assert fade_uniform(None) == (0.0, 0.0)
    assert fade_uniform((0.5, FADE_OUT)) == (0.5, 1.0)
    assert fade_uniform((1.5, FADE_IN)) == (1.0, -1.0)
    with pytest.raises(ValueError, match="fade"):
        fade_uniform((float("nan"), FADE_IN))
    with pytest.raises(ValueError, match="fade"):
        fade_uniform((0.5, 0))
