"""Real glTF models (/work/shared/assets): each renders, and its culling bounds
contain the CPU-animated mesh at 60 times over every clip (not just baked frames)."""
from pathlib import Path

import numpy as np
import pytest

from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from render.renderer import Renderer
from sim.gltf import load as gltf_load
from sim.state import CrowdState

ASSETS = Path(__file__).resolve().parents[3] / "shared" / "assets"
MODELS = sorted(ASSETS.glob("*.glb")) if ASSETS.is_dir() else []

pytestmark = pytest.mark.skipif(not MODELS, reason=f"no glTF assets folder at {ASSETS}")


@pytest.fixture(scope="module")
def renderer(gl_ctx):
    r = Renderer((200, 150), ctx=gl_ctx, debug=True)
    yield r
    r.release()


@pytest.fixture(scope="module", params=MODELS, ids=[p.stem for p in MODELS])
def model(request):
    ch = gltf_load.load_gltf(request.param)
    return ch, build_rep(ch, fps=30)


def _inside(points, sphere, tol):
    return bool((np.linalg.norm(points - sphere[:3], axis=1) <= sphere[3] * (1 + 1e-5) + tol).all())


def test_model_renders_non_empty(renderer, model):
    ch, rep = model
    renderer.upload(rep)
    sph = rep.part_sphere()[0]
    c, r = sph[:3], max(float(sph[3]), 1e-3)
    cam = Camera.look_at(c + np.array([0.3, 0.4, 2.5]) * r, c, near=0.01 * r, far=20 * r)
    st = CrowdState.empty(1)
    dl = NoLodSelector([rep]).select(st, cam, renderer.size)
    assert dl.n_instances == 1
    t = renderer.draw(dl, background=(0, 0, 0))
    px = renderer.read_pixels()
    assert t["samples_passed"] > 100
    assert (px.max(axis=2) > 8).sum() > 100


def test_bounds_contain_the_cpu_animated_mesh_at_60_times(model):
    ch, rep = model
    if rep.kind == "skinned":
        from sim.skinning import skin

        for c, name in enumerate(rep.clip_names):
            clip = ch.clips[name]
            lo, hi = rep.clip_aabb[c].astype(np.float64)
            tol = 1e-5 * float(np.ptp(rep.clip_aabb[c], axis=0).max())
            mats = clip.skinning_matrices(ch.skeleton, np.linspace(0.0, clip.duration, 60))
            for k, m in enumerate(mats):
                p, _ = skin(ch.mesh, m)
                assert (p >= lo - tol).all() and (p <= hi + tol).all(), f"{name}: sample {k} leaves the box"
                assert _inside(p, rep.clip_sphere[c], tol), f"{name}: sample {k} leaves the sphere"
    else:
        for a, name in enumerate(rep.anim_names):
            anim = ch.animations[name]
            lo_t = float(rep.anim_t0[a])
            for t in np.linspace(lo_t, lo_t + float(rep.anim_duration[a]), 60):
                p = np.asarray(anim.interpolate(t)[0], np.float64)
                seg, _ = rep.locate(a, np.array([t]))
                tol = 1e-5 * float(rep.seg_sphere[seg[0], 3])
                assert _inside(p, rep.seg_sphere[seg[0]], tol), f"{name}: t={t} leaves segment {seg[0]}'s sphere"
