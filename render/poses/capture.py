"""Transform-feedback capture of a representation's vertices (moved out of
``render/renderer.py``): the very vertex shader of the draw, run for each
instance, its positions and normals read back (tests compare them with the CPU
skinning reference)."""
from __future__ import annotations

import numpy as np

from lod.drawlist import INSTANCE_FLOATS
from render.poses.targets import use_targets


def capture(renderer, key: str, instance_data: np.ndarray, part: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Vertex positions and normals as the draw shader computes them.

    Runs the representation's vertex shader (the same GLSL, via transform
    feedback) for each instance and returns camera-relative world
    positions (k, V, 3) float32 and un-normalised normals (k, V, 3) float32,
    V = vertices of the representation (all segments for keyframed reps;
    ``part`` is unused and kept for symmetry with draws).
    """
    g = renderer._reps[key]
    data = np.ascontiguousarray(instance_data, np.float32).reshape(-1, INSTANCE_FLOATS)
    k = data.shape[0]
    V = g.n_vertices
    ctx = renderer.ctx
    inst = ctx.buffer(data.tobytes())
    out = ctx.buffer(reserve=max(1, k * V * 24))
    try:
        # a draw needs a complete framebuffer even with rasterisation
        # discarded, and a headless context's default one is not
        renderer.fbo.use()
        prog = g.capture_vao.program
        if "u_view_proj" in prog:
            prog["u_view_proj"].write(np.eye(4, dtype=np.float32).tobytes())
        if "u_joints" in prog:
            prog["u_joints"].value = 0
        if "u_palette" in prog:
            base = renderer._build_palette([(g, inst, 0, k)])[0]
            renderer.fbo.use()
            prog["u_palette"].value = 1
            prog["u_palette_base"].value = base
            prog["u_palette_stride"].value = 3 * g.n_joints
        if g.joints is not None:
            g.joints.use(0)
        use_targets(prog, g.targets)  # no-op without morph targets
        renderer._bind_instances(g.capture_vao, g.capture_locs, inst, 0)
        g.capture_vao.transform(out, ctx.POINTS, vertices=V, instances=k)
        res = np.frombuffer(out.read(), np.float32).reshape(k, V, 6)
    finally:
        out.release()
        inst.release()
    return res[:, :, :3].copy(), res[:, :, 3:].copy()
