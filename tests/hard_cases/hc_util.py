"""Shared helpers of the hard-case suite (module name unique under tests/)."""
import numpy as np

from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from render.renderer import INSTANCE_BYTES, Renderer
from sim.state import CrowdState


def crowd(n, character=0, clip=0, spacing=1.0, origin=(0.0, 0.0, 0.0)):
    st = CrowdState.empty(n)
    k = int(np.ceil(np.sqrt(max(n, 1))))
    i = np.arange(n)
    st.position[:, 0] = (i % k) * spacing + origin[0]
    st.position[:, 1] = origin[1]
    st.position[:, 2] = (i // k) * spacing + origin[2]
    st.character[:] = character
    st.clip[:] = clip
    return st


def render_frames(ctx, characters, state, camera, times, size=(96, 64), step=None):
    """Render ``state`` at each anim time in ``times``; returns the images.
    Every frame: DrawList instance data finite (the debug Renderer raises
    otherwise), images finite."""
    reps = [build_rep(c, key=f"hc:{i}") for i, c in enumerate(characters)]
    sel = NoLodSelector(reps)
    images = []
    with Renderer(size, ctx=ctx, debug=True) as r:
        for rep in reps:
            r.upload(rep)
        for t in times:
            state.anim_time[:] = t
            if step is not None:
                step(state)
            dl = sel.select(state, camera, size)
            for b in dl.batches:
                assert np.isfinite(b.instance_data).all()
            r.draw(dl)
            images.append(r.read_pixels().copy())
    return images, reps, sel


def look(position, target, near=0.1, far=1000.0, fov=50.0):
    return Camera.look_at(position, target, fov_y=fov, near=near, far=far)


def check_frame(r: Renderer, dl) -> None:
    """The frame's DrawList, the used part of the instance buffer and the
    vertex shader's outputs of every drawn triangle representation: finite."""
    batches = [b for b in dl.batches if b.n_instances]
    for b in batches:
        assert np.isfinite(np.asarray(b.instance_data, np.float64)).all(), b.rep
    used = sum(b.n_instances for b in batches if b.rep in r._reps) * INSTANCE_BYTES
    if used:
        gpu = np.frombuffer(r._instances.read(size=used), np.float32)
        assert np.isfinite(gpu).all()
    for b in batches[:4]:
        if b.rep in r._reps and r._reps[b.rep].n_vertices:
            pos, nrm = r.capture(b.rep, np.asarray(b.instance_data, np.float32)[:8])
            assert np.isfinite(pos).all() and np.isfinite(nrm).all(), b.rep
