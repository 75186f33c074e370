"""Shared helpers of the hard-case suite (module name unique under tests/)."""
import numpy as np

from lod.nolod import NoLodSelector, build_rep
from lod.view import Camera
from render.renderer import Renderer
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
