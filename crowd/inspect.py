"""``crowd inspect``: look at a character's VDR-AM cluster hierarchy with pyvista.

Claudio, Kim, Kim, Yoon, *VDR-AM*. Three views of one skinned character, side
by side, in the pose chosen on the command line:

1. **clusters** (the paper's Fig. 7): every leaf cluster of the error-aware
   (or octree) clustering in its own colour, so the §4.2 clustering is seen;
2. **deformation** (Fig. 11, left): the §4.2 deformation level of every leaf
   cluster (the largest of its vertices', metres) as a heat map;
3. **cut** (Fig. 11, right): the §5.1 LOD cut a view selects at the given
   pixels of error, drawn with the selected (simplified) clusters, each
   triangle coloured by its cluster's height in the hierarchy (0 = leaf, full
   resolution; higher = coarser), with the triangle count in the title.

Usage::

    crowd inspect ASSET [--png FILE] [--clip NAME] [--time SECONDS] [--pose K]
                        [--poe PIXELS] [--camera X,Y,Z] [--size WxH] [--clustering octree]

ASSET is what ``crowd info`` takes: a ``.glb``/``.gltf`` file with a skin, or
``generator:humanoid[:TRIANGLES[:SEED]]`` / ``generator:quadruped[...]``.
``--pose K`` shows the hierarchy's K-th representative pose (§4.1) instead
of ``--clip``/``--time``. ``--camera`` is the eye in model space (metres; the
view looks at the model's centre); by default it stands in front of the model
at 2.5 times its size. The cut is computed for the eye, the image height and
the field of view (30 degrees) of that view. Without ``--png`` a window opens
(needs a display); with ``--png`` the image is rendered off screen (VTK's EGL
window, no display needed) and written atomically.

The hierarchy comes from the same on-disk cache as LOD mode ``"clusters"``
(``$CROWD_CACHE_DIR``) and is built (with a progress bar) when missing.
pyvista is an optional dependency (``pip install crowd-sandbox[inspect]``); it
is imported only by this command.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from crowd.errors import AssetError, CrowdError

#: vertical field of view of the inspection camera, degrees
FOV_Y = 30.0
#: default window / image size
DEFAULT_SIZE = (1500, 600)


def cluster_colors(n: int, seed: int = 7) -> np.ndarray:
    """(n, 3) uint8 distinct, saturated colours (golden-ratio hues, varied value), one per cluster."""
    k = np.arange(int(n))
    rng = np.random.default_rng(seed)
    h = (rng.permutation(max(int(n), 1))[:n] * 0.6180339887) % 1.0 if n else np.zeros(0)
    s = 0.55 + 0.4 * ((k * 7) % 5) / 4.0
    v = 0.65 + 0.35 * ((k * 3) % 4) / 3.0
    i = np.floor(h * 6.0).astype(int) % 6
    f = h * 6.0 - np.floor(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    rgb = np.select([i[:, None] == j for j in range(6)],
                    [np.stack(x, 1) for x in ((v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q))])
    return np.round(rgb * 255).astype(np.uint8).reshape(-1, 3)


def _pose_matrices(character, h, clip: str | None, time: float | None, pose: int | None) -> tuple:
    """(J, 4, 4) skinning matrices of the requested pose and a label for it."""
    if pose is not None:
        reps = np.asarray(h.representatives, np.int64)
        if not 0 <= int(pose) < reps.size:
            raise CrowdError(f"--pose: expected a representative pose index in 0..{reps.size - 1}, got {pose}")
        s = int(reps[int(pose)])
        name = h.pose_clips[int(h.pose_clip[s])]
        t = float(h.pose_times[s])
        return character.clip(name).skinning_matrices(character.skeleton, np.array([t]))[0], \
            f"representative pose {pose} ({name} at {t:.2f} s)"
    names = list(character.clips)
    if clip is None:
        clip = names[0] if names else None
    if clip is None:
        return np.tile(np.eye(4), (character.skeleton.n_joints, 1, 1)), "rest pose"
    if clip not in names:
        raise CrowdError(f"--clip: the character has no clip {clip!r}; it has {', '.join(names)}")
    c = character.clip(clip)
    t = float(time or 0.0)
    if not (0.0 <= t <= float(c.duration)):
        raise CrowdError(f"--time: expected seconds in 0..{float(c.duration):.3g} for clip {clip!r}, got {t}")
    return c.skinning_matrices(character.skeleton, np.array([t]))[0], f"{clip} at {t:.2f} s"


def inspect_data(character, h, clip=None, time=None, pose=None, poe: float = 1.0, camera=None,
                 size=DEFAULT_SIZE) -> dict:
    """Everything the three views show, as plain arrays (no pyvista; tests read this).

    Parameters
    ----------
    character : sim.character.SkinnedCharacter
    h : lod.clusters.dag.ClusterHierarchy of ``character``
    clip, time, pose : the pose (see the module docstring)
    poe : float >= 0, pixels of error of the cut
    camera : (3,) eye in model space, or None (in front at 2.5 model sizes)
    size : (width, height) pixels of the whole image (the cut uses the height)

    Returns
    -------
    dict with ``positions`` (V, 3) float64 posed vertices; ``leaf_triangles``
    (T, 3) int64; ``leaf_of_triangle`` (T,) int64 leaf cluster per triangle;
    ``leaf_colors`` (L, 3) uint8; ``leaf_deformation`` (L,) float; ``cut`` (k,)
    int32 clusters of the cut; ``cut_triangles`` (t, 3) int64;
    ``cut_height`` (t,) int cluster height per cut triangle; ``eye`` (3,);
    ``target`` (3,); ``pose_label`` str; ``poe`` float.
    """
    from lod.clusters import cut as cluster_cut
    from lod.clusters.dag import skin_poses

    mats, label = _pose_matrices(character, h, clip, time, pose)
    X = skin_poses(character.mesh, mats[None])[0]
    L = h.n_leaves
    leaf_tris = [h.cluster_triangles(i).astype(np.int64) for i in range(L)]
    tri = np.concatenate(leaf_tris) if L else np.zeros((0, 3), np.int64)
    leaf_of = np.repeat(np.arange(L), [t.shape[0] for t in leaf_tris])
    lo, hi = X.min(axis=0), X.max(axis=0)
    target = 0.5 * (lo + hi)
    height = float(max(hi[1] - lo[1], np.linalg.norm(hi - lo), 1e-6))
    if camera is None:
        eye = target + np.array([0.0, 0.0, 2.5 * height])
    else:
        eye = np.asarray(camera, np.float64).reshape(3)
    if not np.all(np.isfinite(eye)) or np.linalg.norm(eye - target) < 1e-9:
        raise CrowdError(f"--camera: expected a finite eye position away from the model centre, got {list(eye)}")
    poe = float(poe)
    if not (poe >= 0.0 and np.isfinite(poe)):
        raise CrowdError(f"--poe: expected a finite number of pixels >= 0, got {poe}")
    scale = cluster_cut.viewport_scale(size[1], FOV_Y)
    off, cut = cluster_cut.cut(h, np.eye(4)[None], eye, scale, poe)
    ct = [h.cluster_triangles(int(i)).astype(np.int64) for i in cut]
    cut_tris = np.concatenate(ct) if ct else np.zeros((0, 3), np.int64)
    cut_h = np.repeat(h.height[cut].astype(np.int64), [t.shape[0] for t in ct]) if ct else np.zeros(0, np.int64)
    return {"positions": X, "leaf_triangles": tri, "leaf_of_triangle": leaf_of, "leaf_colors": cluster_colors(L),
            "leaf_deformation": np.asarray(h.deformation[:L], np.float64), "cut": cut, "cut_triangles": cut_tris,
            "cut_height": cut_h, "eye": eye, "target": target, "pose_label": label, "poe": poe,
            "n_triangles": int(h.n_triangles)}


def _polydata(pv, X, tris):
    faces = np.hstack([np.full((tris.shape[0], 1), 3, np.int64), tris]).reshape(-1)
    return pv.PolyData(np.asarray(X, np.float32), faces)


def _import_pyvista(offscreen: bool):
    if offscreen and not os.environ.get("DISPLAY"):
        # no X server: VTK's EGL render window (Mesa llvmpipe here), without the X warning first
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        import pyvista as pv
    except ImportError:
        raise CrowdError("crowd inspect needs pyvista: install it with `pip install pyvista` "
                         "(or `pip install crowd-sandbox[inspect]`)") from None
    if offscreen:
        pv.OFF_SCREEN = True
    return pv


def render(data: dict, png: str | os.PathLike | None = None, size=DEFAULT_SIZE, title: str = "") -> None:
    """Show the three views in a window, or write them to ``png`` (off screen, atomically)."""
    pv = _import_pyvista(png is not None)
    X, tri = data["positions"], data["leaf_triangles"]
    p = pv.Plotter(shape=(1, 3), off_screen=png is not None, window_size=tuple(int(x) for x in size),
                   border=False)
    eye, target = data["eye"], data["target"]
    up = (0.0, 1.0, 0.0) if abs((eye - target)[1]) < 0.99 * np.linalg.norm(eye - target) else (0.0, 0.0, 1.0)

    def view(col, mesh, subtitle, **kw):
        p.subplot(0, col)
        p.add_mesh(mesh, **{"show_edges": False, **kw})
        p.add_text(subtitle, font_size=9)
        p.camera_position = [tuple(eye), tuple(target), up]
        p.camera.view_angle = FOV_Y

    m = _polydata(pv, X, tri)
    m.cell_data["colour"] = data["leaf_colors"][data["leaf_of_triangle"]]
    view(0, m, f"{title}\nleaf clusters (Fig. 7): {data['leaf_colors'].shape[0]}", scalars="colour", rgb=True)
    d = _polydata(pv, X, tri)
    d.cell_data["deformation level (m)"] = data["leaf_deformation"][data["leaf_of_triangle"]]
    view(1, d, f"deformation level per cluster, {data['pose_label']}", scalars="deformation level (m)",
         cmap="inferno")
    c = _polydata(pv, X, data["cut_triangles"])
    c.cell_data["cluster height"] = data["cut_height"].astype(np.float64)
    view(2, c, f"cut at PoE {data['poe']:g}: {data['cut_triangles'].shape[0]:,} of {data['n_triangles']:,} "
               f"triangles, {data['cut'].size} clusters", scalars="cluster height", cmap="viridis",
         show_edges=True, edge_color="black", line_width=0.3)
    if png is None:
        p.show()
        return
    png = Path(png)
    if png.parent and not png.parent.is_dir():
        p.close()
        raise CrowdError(f"--png: the folder {str(png.parent)!r} does not exist")
    fd, tmp = tempfile.mkstemp(dir=str(png.parent), prefix=".inspect-", suffix=".png")
    os.close(fd)
    try:
        p.screenshot(tmp, return_img=False)
        p.close()
        from PIL import Image

        Image.open(tmp).convert("RGB").save(tmp, format="PNG")
        os.replace(tmp, png)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def load(asset: str, clustering: str = "error-aware", quiet: bool = False, clip: str | None = None):
    """(character, hierarchy) of an asset spec (``crowd info`` syntax); CrowdError when it has no skin or no
    clip named ``clip`` (checked before the hierarchy is built: a typo costs no build)."""
    from crowd.characters import build_character, parse_asset
    from lod.clusters.mode import cached_hierarchy
    from lod.full.reps import build_skinned_rep

    spec = parse_asset(asset)
    ch = build_character(spec)
    if getattr(ch, "kind", "") != "skinned" or not ch.mesh.is_skinned:
        raise AssetError(f"{asset}: the character has no skin (joints and weights); crowd inspect shows the "
                         f"cluster hierarchy of skinned characters only")
    sk = build_skinned_rep(ch, key=f"clusters:{ch.name}", morph_targets=False)  # as lod.clusters.mode
    h = cached_hierarchy(ch, sk, {"clustering_method": clustering}, quiet=quiet)
    return ch, h


def main(args) -> int:
    """The ``crowd inspect`` command (``args`` from :func:`crowd.cli.build_parser`)."""
    if args.png is not None:
        out = Path(args.png)
        if out.suffix.lower() != ".png":
            raise CrowdError(f"--png: expected a file name ending in .png, got {str(out)!r}")
        if not out.parent.is_dir():
            raise CrowdError(f"--png: the folder {str(out.parent)!r} does not exist")
    elif not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise CrowdError("crowd inspect: no display to open a window on (DISPLAY is not set); "
                         "write an image instead with --png FILE")
    size = tuple(args.size) if args.size else DEFAULT_SIZE
    ch, h = load(args.asset, args.clustering, clip=args.clip)
    data = inspect_data(ch, h, clip=args.clip, time=args.time, pose=args.pose, poe=args.poe, camera=args.camera,
                        size=size)
    render(data, args.png, size=size, title=f"{args.asset}: {h.n_clusters} clusters, {h.n_triangles:,} triangles")
    if args.png is not None:
        print(f"wrote {args.png}: {data['leaf_colors'].shape[0]} leaf clusters, cut of "
              f"{data['cut_triangles'].shape[0]:,} triangles at PoE {data['poe']:g}")
    return 0
