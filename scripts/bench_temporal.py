"""Keyframed view-dependent selection (Friedrich, Polthier & Schmies §3-4): popping and selection cost.

Two parts, each comparing per-frame selection with selection every n-th frame
blended in between:

1. The crowd of ``scenes/horses.toml`` (fewer horses and a smaller image than the
   scene, for run time; both printed) in LOD mode "triangles" (levels faded) or
   "clusters" (``--mode clusters``: cuts geomorphed, :mod:`lod.clusters.morph`,
   and a faded variant for comparison), rendered along
   the scene's camera path next to the full-detail reference (mode "none").
   Per setting: selection time per displayed frame (the view-dependent part,
   i.e. the mode's ``select`` calls, and the whole ``select`` call including the
   per-frame pack of current transforms), triangles drawn, image error against
   the reference (mean |difference| per frame, mean and max over frames) and
   the LOD flicker: :func:`crowd.image_metrics.flicker`, the mean image change
   between consecutive frames that the reference does not have, and its peak,
   ``max |G * ((F_t - F_t-1) - (R_t - R_t-1))|`` with G a Gaussian of sigma
   ``--blur`` pixels (the eye integrates a screen-door pattern; a pop is a
   large local change, a blend spreads it over n frames).
   Mode "clusters" adds the measure of part 2 for the crowd: the screen-space
   deviation ``e_t(v)`` (pixels) of sampled original vertices between where
   the representation draws them (the vertex of the cut's cluster they
   collapsed into, blended by the geomorph) and the full-detail mesh, per
   frame its mean (error) and, between consecutive frames, the largest
   ``|e_t(v) - e_t-1(v)|`` (flicker: the change of the drawn surface that the
   reference does not have).
2. The bisection terrain (lod/temporal/terrain_keyframes.py) over a 513 x 513 grid: 2^19 leaf
   triangles, 2^20 triangles in its binary hierarchy, on the fly-through of
   ``scripts/bench_terrain_lod.py``: the same figures in screen-space pixels
   of vertex deviation, for per-frame selection and keyframed selection with
   linear blending, and the three §4.1 extrapolation modes' error terms.

Usage: ``python scripts/bench_temporal.py [--frames 40] [--horses 300] [--size 480 270] [--n 8]
[--mode triangles|clusters] [--ss 1] [--part both|crowd|terrain]``.
"""
from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: repetitions of the selection-only timing pass
REPEATS = 5
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))


def popping(prev, cur, ref_prev, ref_cur, sigma: float) -> float:
    """Peak local LOD flicker: max over pixels of the Gaussian-blurred (sigma px)
    temporal change the reference does not have (grey level, images in [0, 1])."""
    from scipy.ndimage import gaussian_filter

    from crowd.image_metrics import as_float

    d = (as_float(cur) - as_float(prev)) - (as_float(ref_cur) - as_float(ref_prev))
    return float(np.abs(gaussian_filter(d.mean(axis=2), sigma)).max())


def _levels(dl) -> dict:
    """agent id -> (rep, part, level) of a DrawList's unfaded agent batches."""
    out = {}
    for b in dl.batches:
        if b.fade is None:
            for i in np.asarray(b.instance_ids).tolist():
                if i >= 0:
                    out[i] = (b.rep, b.part, b.level)
    return out


def restage(prev, cur):
    """``prev``'s representations (batches, levels, fades) drawn with ``cur``'s
    transforms and camera: the frame ``cur`` would be had the selection not
    changed since ``prev``. Agents ``prev`` did not draw keep ``cur``'s batches;
    agents ``cur`` does not draw are left out."""
    import dataclasses

    from lod.temporal.selection import take_rows

    rows, part = {}, {}
    for b in cur.batches:
        for i, d in zip(np.asarray(b.instance_ids).tolist(), np.asarray(b.instance_data)):
            if i >= 0:
                rows[i] = d
                part[i] = (b.representation, b.part)  # a clip change is not a LOD switch: keep cur's
    seen = set()
    out = []
    for b in prev.batches:
        ids = np.asarray(b.instance_ids)
        if ids.size and ids[0] < 0:
            continue
        keep = np.array([i in rows and part[i] == (b.representation, b.part) for i in ids.tolist()], bool)
        if keep.any():
            r = np.flatnonzero(keep)
            out.append(take_rows(b, r, ids[r], np.stack([rows[i] for i in ids[r].tolist()]), fade=b.fade,
                                 triangles=b.triangles, points=b.points))
            seen.update(ids[r].tolist())
    for b in cur.batches:
        ids = np.asarray(b.instance_ids)
        if ids.size and ids[0] < 0:
            out.append(b)
            continue
        keep = np.array([i not in seen for i in ids.tolist()], bool)
        if keep.any():
            r = np.flatnonzero(keep)
            out.append(take_rows(b, r, ids[r], np.asarray(b.instance_data)[r], fade=b.fade))
    return dataclasses.replace(cur, batches=out)


#: ``--path close``: a low dolly into the herd (replaces the scene's camera keys)
CLOSE_PATH = """[camera]
fov = 50.0
near = 0.5
far = 1500.0
keys = [
  { time = 0.0, position = [-150.0, 10.0, 70.0], target = [-120.0, 2.0, 0.0] },
  { time = 2.0, position = [-125.0, 5.0, 20.0], target = [-110.0, 1.5, -10.0] },
]
"""


#: sampled original vertices per character for the crowd's screen-space deviation measure
DEVIATION_SAMPLES = 400
#: PoE of the keyframed geomorph run whose mean error matches per-frame selection's (the union
#: of two cuts is slightly coarser than the current cut while the camera approaches)
MATCHED_POE = 0.9


def deviation_setup(reps, samples: int = DEVIATION_SAMPLES, seed: int = 0) -> dict:
    """Per rep key with vertex collapses: (collapse next, collapse height/level, height of each cluster or
    None for a LOD chain, leaf range arrays or None, skinned rep, sampled vertices (S,), a leaf cluster
    holding each or None)."""
    from lod.clusters.morph import collapse_table

    rng = np.random.default_rng(seed)
    out = {}
    for r in reps:
        if getattr(r, "kind", "") == "clusters":
            h = r.hierarchy
            leaf_tris = np.asarray(h.indices[:h.tri_start[h.n_leaves]], np.int64)
            owner = np.repeat(np.arange(h.n_leaves), np.diff(h.tri_start[:h.n_leaves + 1]))
            verts, first = np.unique(leaf_tris.reshape(-1), return_index=True)
            pick = rng.choice(verts.shape[0], min(samples, verts.shape[0]), replace=False)
            out[r.key] = (*collapse_table(h), h, r.skinned, verts[pick], owner[first[pick] // 3])
        elif getattr(r, "collapse_next", None) is not None:  # a LOD chain (lod.chains.mode)
            verts = np.unique(np.asarray(r.level_indices(0), np.int64))
            pick = rng.choice(verts.shape[0], min(samples, verts.shape[0]), replace=False)
            out[r.key] = (r.collapse_next, r.collapse_level, None, r, verts[pick], None)
    return out


def _skin_at(sk, verts: np.ndarray, frame: float) -> np.ndarray:
    """(m, 3) float64 model-space positions of ``verts`` skinned at a fractional row of the baked
    joint table (as the GPU does: matrices of the two neighbouring rows blended)."""
    f0 = int(np.clip(np.floor(frame), 0, sk.joint_table.shape[0] - 1))
    f1 = min(f0 + 1, sk.joint_table.shape[0] - 1)
    a = float(frame) - np.floor(frame)
    M = (1 - a) * sk.joint_table[f0].astype(np.float64) + a * sk.joint_table[f1].astype(np.float64)  # (J, 3, 4)
    j = np.asarray(sk.joints, np.int64)[verts]
    w = np.asarray(sk.weights, np.float64)[verts]
    p = np.c_[np.asarray(sk.positions, np.float64)[verts], np.ones(verts.shape[0])]
    return np.einsum("vk,vkij,vj->vi", w, M[j], p)


def vertex_deviations(dl, setup: dict) -> dict:
    """agent id -> (S, 2) screen-space deviation (pixels) of the sampled vertices, drawn minus
    full detail, for every agent a cluster or chain batch draws unfaded (NaN rows: vertex culled)."""
    from lod.clusters.morph import chain_targets

    VP = np.asarray(dl.proj, np.float64) @ np.asarray(dl.view, np.float64)
    W, H = dl.size
    out = {}

    def px(q):  # camera-relative world (m, 3) -> pixels (m, 2)
        c = np.c_[q, np.ones(q.shape[0])] @ VP.T
        w = np.where(np.abs(c[:, 3]) > 1e-9, c[:, 3], np.nan)
        return np.c_[(c[:, 0] / w * 0.5 + 0.5) * W, (c[:, 1] / w * 0.5 + 0.5) * H]

    for b in dl.batches:
        st = setup.get(b.rep)
        if st is None or b.fade is not None:
            continue
        nxt, rem, h, sk, verts, leaf = st
        data = np.asarray(b.instance_data, np.float64)
        if h is None:  # a chain level, geomorphed towards a coarser one or not
            if getattr(b, "index_range", None) is None:
                continue
            u_all = chain_targets(nxt, rem, verts, int(b.level))
            m = getattr(b, "morph", None)
            x_all = chain_targets(nxt, rem, u_all, int(m[0])) if m is not None else u_all
            w_all = np.full(verts.shape[0], float(m[1]) if m is not None else 0.0)
        for i, agent in enumerate(np.asarray(b.instance_ids).tolist()):
            ok = np.ones(verts.shape[0], bool)
            if h is not None:  # a cluster cut (or a geomorphed union of two)
                if not hasattr(b, "offsets"):
                    break
                e = slice(int(b.offsets[i]), int(b.offsets[i + 1]))
                ent = np.asarray(b.clusters[e], np.int64)
                if not ent.size:
                    continue
                order = np.argsort(h.leaf_lo[ent], kind="stable")
                ent = ent[order]
                j = np.searchsorted(h.leaf_lo[ent], leaf, side="right") - 1
                jj = np.clip(j, 0, ent.shape[0] - 1)
                ok = (j >= 0) & (leaf < h.leaf_hi[ent[jj]])
                u = chain_targets(nxt, rem, verts, h.height[ent[jj]])
                mh, mw = getattr(b, "morph_height", None), getattr(b, "morph_weight", None)
                if mh is not None:
                    hm = np.asarray(mh[e], np.int64)[order][jj]
                    wm = np.asarray(mw[e], np.float64)[order][jj]
                    x = np.where(hm >= 0, chain_targets(nxt, rem, u, hm), u)
                else:
                    wm, x = np.zeros(verts.shape[0]), u
            else:
                u, x, wm = u_all, x_all, w_all
            allv = np.unique(np.concatenate([verts, u, x]))
            P = _skin_at(sk, allv, data[i, 12])
            look = lambda v: P[np.searchsorted(allv, v)]  # noqa: E731
            drawn = (1 - wm)[:, None] * look(u) + wm[:, None] * look(x)
            M = data[i, :12].reshape(3, 4)
            true_w = look(verts) @ M[:, :3].T + M[:, 3]
            drawn_w = drawn @ M[:, :3].T + M[:, 3]
            d = px(drawn_w) - px(true_w)
            d[~ok] = np.nan
            out[agent] = d
    return out


def deviation_step(prev: dict, cur: dict):
    """(mean |e_t|, largest |e_t - e_t-1|, mean |e_t - e_t-1|) over the sampled vertices of agents
    drawn in both frames (pixels); ``prev`` None gives NaN flicker."""
    errs = [np.linalg.norm(d, axis=1) for d in cur.values()]
    errs = np.concatenate(errs) if errs else np.zeros(0)
    err = float(np.nanmean(errs)) if np.isfinite(errs).any() else float("nan")
    if prev is None:
        return err, float("nan"), float("nan")
    ch = [np.linalg.norm(cur[a] - prev[a], axis=1) for a in cur if a in prev]
    ch = np.concatenate(ch) if ch else np.zeros(0)
    ch = ch[np.isfinite(ch)]
    return err, float(ch.max()) if ch.size else 0.0, float(ch.mean()) if ch.size else 0.0


def downsample(img: np.ndarray, ss: int) -> np.ndarray:
    """(h, w, c) float image in [0, 1]: the mean of every ss x ss block of a (ss h, ss w, c) image."""
    from crowd.image_metrics import as_float

    a = as_float(img)
    if ss == 1:
        return a
    h, w = a.shape[0] // ss, a.shape[1] // ss
    return a[:h * ss, :w * ss].reshape(h, ss, w, ss, -1).mean(axis=(1, 3))


def crowd_part(frames: int, horses: int, size, n: int, poe: float, sigma: float, speed: float,
               still: bool = False, path: str = "scene", lod_mode: str = "triangles", ss: int = 1) -> None:
    from crowd.engine import Engine
    from crowd.image_metrics import as_float, flicker
    from crowd.scene import load_scene
    from lod.clusters import mode as cm_mode
    from lod.chains import mode as tm
    from lod.temporal.selection import KeyframedSelector, subset_state
    from scipy.ndimage import gaussian_filter

    text = (REPO / "scenes" / "horses.toml").read_text()
    text = re.sub(r"count = \d+", f"count = {horses}", text)
    text = text.replace('mode = "none"', f'mode = "{lod_mode}"\npoe = {poe}')
    if path == "close":
        a, b = text.index("[camera]"), text.index("[render]")
        text = text[:a] + CLOSE_PATH + "\n" + text[b:]
    text = re.sub(r"time = ([0-9.]+)", lambda m: f"time = {float(m.group(1)) / speed}", text)  # path speed-up
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "horses_bench.toml"
        p.write_text(text)
        scene = load_scene(p)
        e = Engine(scene, overrides={"size": tuple(size), "frames": frames}, quiet=True)
    reps = e.reps
    ref = e._build_mode("none")[1]

    def inner(p=poe):
        if lod_mode == "clusters":
            return cm_mode.ClustersSelector(reps, static_reps=e.statics, poe=p)
        return tm.TrianglesSelector(reps, static_reps=e.statics, poe=p)

    settings = [("full detail (reference)", ref, None), ("per-frame selection", e.selector, None)]
    variants = [("current", True, poe), ("current", False, poe), ("current", True, round(MATCHED_POE * poe, 3)),
                ("extrapolated", True, poe), ("delayed", True, poe)]
    for mode, morph, p in variants:
        k = KeyframedSelector(inner(p), n=n, mode=mode, geomorph=morph)
        label = f"keyframed n={n}, {mode}" + (", geomorph" if morph else ", fade")
        if p != poe:
            label += f", poe {p:g} (error matched)"
        settings.append((label, k, k, p))
    settings = [x if len(x) == 4 else (*x, poe) for x in settings]
    dev_setup = deviation_setup(reps)
    dev = {name: {"err": [], "fmax": [], "fmean": [], "prev": None} for name, *_ in settings}
    # the LOD is selected for ``size``; images are rendered ss x larger and box-filtered down (an
    # antialiased image: a sub-pixel move of an edge changes its pixels a little instead of flipping them)
    r = e.open_renderer((size[0] * ss, size[1] * ss))
    statics = [(s.key, np.eye(4)) for s in e.statics]
    bg = scene.render.background
    acc = {name: {"sel": [], "call": [], "tri": [], "err": [], "fl": [], "pop": [], "trans": [], "changes": [],
                  "sw": [], "swl1": []}
           for name, *_ in settings}
    prev = {}
    print(f"# crowd: scenes/horses.toml with {horses} horses (scene: 2500) of "
          f"{e.plan.triangles(0)} triangles, {size[0]}x{size[1]} (scene: 1280x720), {frames} frames, "
          f"camera path {'of the scene' if path == 'scene' else '`--path close` (a dolly into the herd)'} "
          f"{speed:g}x as fast, mode {lod_mode} poe = {poe} px, n = {n}"
          + (f", images rendered at {ss}x{ss} supersampling and box-filtered" if ss > 1 else "")
          + ("; herd frozen (no simulation step: only the camera moves)" if still else ""))
    last_levels = {}
    last_dl = {}
    if still:
        e.step()  # one step places the herd on the terrain (terrain_follow); then it stays frozen
    cam0 = e.camera_at(0.0)
    for _, sel, k, _ in settings:  # warm-up (JIT, caches): not timed
        sel.select(e.world.state, cam0, tuple(size), statics=statics)
        if k is not None:
            k.reset()
    replay = []  # (state copy, camera) per frame, for the selection-only timing passes
    for f in range(frames):
        if still:
            t_sim = (f + 1) * scene.dt
        else:
            e.step()
            t_sim = e.world.time
        cam = e.camera_at(t_sim)
        replay.append((subset_state(e.world.state, np.arange(e.world.state.n)), cam))
        imgs = {}
        for name, sel, k, _ in settings:
            t0 = time.perf_counter()
            dl = sel.select(e.world.state, cam, tuple(size), statics=statics)
            call = time.perf_counter() - t0
            r.draw(dl, bg)
            imgs[name] = downsample(r.read_pixels(), ss)
            a = acc[name]
            if name in last_dl and name != settings[0][0]:  # the image change due to the selection alone
                r.draw(restage(last_dl[name], dl), bg)
                same_sel = downsample(r.read_pixels(), ss)
                d = as_float(imgs[name]).mean(axis=2) - as_float(same_sel).mean(axis=2)
                a["swl1"].append(float(np.abs(d).mean()))
                a["sw"].append(float(np.abs(gaussian_filter(d, sigma)).max()))
            last_dl[name] = dl
            if dev_setup and name != settings[0][0]:
                cur = vertex_deviations(dl, dev_setup)
                dv = dev[name]
                er, fmax, fmean = deviation_step(dv["prev"], cur)
                dv["err"].append(er)
                if dv["prev"] is not None:
                    dv["fmax"].append(fmax)
                    dv["fmean"].append(fmean)
                dv["prev"] = cur
            a["call"].append(call)
            a["sel"].append(k.last_selection_seconds if k is not None else call)
            a["tri"].append(dl.stats.get("triangles", dl.triangles))
            a["trans"].append(dl.stats.get("transitions", 0))
            lv = _levels(dl)
            if name in last_levels:  # instances drawn unfaded in both frames whose representation switched
                old = last_levels[name]
                a["changes"].append(sum(1 for i, v in lv.items() if i in old and old[i] != v))
            last_levels[name] = lv
        R = imgs[settings[0][0]]
        for name, *_ in settings:
            a = acc[name]
            a["err"].append(float(np.abs(as_float(imgs[name]) - as_float(R)).mean()))
            if prev:
                a["fl"].append(flicker(prev[name], imgs[name], prev[settings[0][0]], R))
                a["pop"].append(popping(prev[name], imgs[name], prev[settings[0][0]], R, sigma))
        prev = imgs
    e.close()
    base = acc["per-frame selection"]
    print()
    print("| setting | selection ms/frame | select call ms/frame | triangles/frame | err mean | err max "
          "| flicker mean (L1) | flicker / per-frame | popping mean (peak) | popping / per-frame "
          "| transitions/frame | pops/frame | switch flicker mean (L1) | switch popping (peak) | / per-frame |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, *_ in settings:
        a = acc[name]
        fl_ratio = np.mean(a["fl"]) / np.mean(base["fl"]) if np.mean(base["fl"]) > 0 else float("nan")
        pop_ratio = np.mean(a["pop"]) / np.mean(base["pop"]) if np.mean(base["pop"]) > 0 else float("nan")
        print(f"| {name} | {1e3 * np.median(a['sel']):.2f} (mean {1e3 * np.mean(a['sel']):.2f}) "
              f"| {1e3 * np.median(a['call']):.2f} | {np.mean(a['tri']):,.0f} | {np.mean(a['err']):.5f} "
              f"| {np.max(a['err']):.5f} | {np.mean(a['fl']):.5f} | {fl_ratio:.2f} | {np.mean(a['pop']):.4f} "
              f"| {pop_ratio:.2f} | {np.mean(a['trans']):.1f} | {np.mean(a['changes'] or [0]):.1f} "
              f"| {np.mean(a['swl1'] or [0]):.6f} | {np.mean(a['sw'] or [0]):.4f} "
              f"| {np.mean(a['sw'] or [0]) / max(np.mean(base['sw']), 1e-12):.2f} |")
    if dev_setup:
        db = dev["per-frame selection"]
        print(f"\n| screen-space vertex deviation ({DEVIATION_SAMPLES} vertices per character) | err mean px "
              f"| err max px (frame means) | flicker max px (mean over frames) | / per-frame | flicker max px "
              f"(worst frame) | flicker mean px | / per-frame |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|")
        for name, _, k, _ in settings[1:]:
            dv = dev[name]
            if not dv["fmax"] or (k is not None and not k.geomorph):
                continue  # a screen-door fade has no single drawn surface
            print(f"| {name} | {np.nanmean(dv['err']):.3f} | {np.nanmax(dv['err']):.3f} "
                  f"| {np.mean(dv['fmax']):.3f} | {np.mean(dv['fmax']) / np.mean(db['fmax']):.2f} "
                  f"| {np.max(dv['fmax']):.3f} | {np.mean(dv['fmean']):.4f} "
                  f"| {np.mean(dv['fmean']) / np.mean(db['fmean']):.2f} |")
    # selection cost per displayed frame, timed again without rendering: the same states and cameras
    # replayed REPEATS times (fresh selectors each time), median of the totals (the machine is shared)
    totals = {name: [] for name, *_ in settings[1:]}
    calls = {name: [] for name, *_ in settings[1:]}
    for _ in range(REPEATS):
        for name, _, k, p in settings[1:]:
            sel = (KeyframedSelector(inner(p), n=n, mode=k.mode, geomorph=k.geomorph) if k is not None else e.selector)
            sel_t = call_t = 0.0
            for st, cam in replay:
                t0 = time.perf_counter()
                sel.select(st, cam, tuple(size), statics=statics)
                dt = time.perf_counter() - t0
                call_t += dt
                sel_t += sel.last_selection_seconds if k is not None else dt
            totals[name].append(sel_t)
            calls[name].append(call_t)
    pf = float(np.median(totals["per-frame selection"]))
    print(f"\n| selection cost (replayed {REPEATS}x without drawing, median) | selection ms/frame "
          f"| / per-frame | select call ms/frame | / per-frame |")
    print("|---|---:|---:|---:|---:|")
    for name in totals:
        t, c = float(np.median(totals[name])), float(np.median(calls[name]))
        print(f"| {name} | {1e3 * t / len(replay):.3f} | {t / pf:.3f} | {1e3 * c / len(replay):.3f} "
              f"| {c / float(np.median(calls['per-frame selection'])):.3f} |")
    print(f"# target: keyframed selection per displayed frame <= 2/n = {2 / n:.3f} of per-frame selection's")


def terrain_part(frames: int, size, n: int, tau: float, resolution: int) -> None:
    from bench_terrain_lod import camera_path

    from lod.temporal.terrain_keyframes import TEMPORAL_MODES, TemporalTerrainLOD, pixel_deviation
    from lod.temporal.terrain import TerrainHierarchy
    from sim.terrain import Terrain

    import tomllib

    with open(REPO / "scenes" / "horses.toml", "rb") as fh:
        table = dict(tomllib.load(fh)["terrain"])
    table["resolution"] = resolution
    terrain = Terrain.from_config(table, str(REPO / "scenes"))
    t0 = time.perf_counter()
    hier = TerrainHierarchy(terrain)
    print(f"\n# terrain: horses terrain at {resolution}^2 samples, grid {hier.n_side}^2, "
          f"{hier.n_full_triangles} leaf triangles ({2 * hier.n_full_triangles} in the hierarchy), "
          f"built in {time.perf_counter() - t0:.2f} s; {frames} frames at {size[0]}x{size[1]}, n = {n}")
    cams = camera_path(terrain, frames)
    full_y = hier.positions[:, 1]
    hier.select(cams[0], size, tau)  # warm the kernels
    print("\n| method | tau px | triangles/frame | LOD ms/frame | selections | err mean px | err max px "
          "| flicker mean px | flicker / per-frame |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    base_fl = None
    for label, nn, tt in (("per-frame selection", 1, tau), (f"keyframed n={n}", n, tau),
                          (f"keyframed n={n}, tau matched", n, tau * 0.85),
                          (f"keyframed n={2 * n}, tau matched", 2 * n, tau * 0.8)):
        lod = TemporalTerrainLOD(hier, size, n=nn, tau=tt, mode="delayed")
        tris, times, err, flick = [], [], [], []
        prev = None
        for cam in cams:
            t0 = time.perf_counter()
            fr = lod.frame(cam)
            mesh = fr.mesh()
            times.append(time.perf_counter() - t0)
            tris.append(mesh.n_triangles)
            err.append(pixel_deviation(hier, full_y, fr.grid_heights, fr.camera, size))
            if prev is not None:
                flick.append(pixel_deviation(hier, fr.grid_heights, prev, fr.camera, size))
            prev = fr.grid_heights
        fl = float(np.mean(flick))
        base_fl = fl if base_fl is None else base_fl
        print(f"| {label} | {tt:.2f} | {np.mean(tris):.0f} | {1e3 * np.median(times):.2f} | {lod.n_selections} "
              f"| {np.mean(err):.3f} | {np.max(err):.3f} | {fl:.3f} | {fl / base_fl:.2f} |")
    print("\n| extrapolation mode | err_inter mean/max px | err_view mean/max px | err_extra mean/max px | delay s |")
    print("|---|---:|---:|---:|---:|")
    for mode in TEMPORAL_MODES:
        lod = TemporalTerrainLOD(hier, size, n=n, tau=tau, mode=mode, measure_errors=True)
        fr = [lod.frame(c) for c in cams][2 * n:]
        ei, ev, ee = ([getattr(x, k) for x in fr] for k in ("err_inter", "err_view", "err_extra"))
        print(f"| {mode} | {np.mean(ei):.3f} / {np.max(ei):.3f} | {np.mean(ev):.3f} / {np.max(ev):.3f} "
              f"| {np.mean(ee):.3f} / {np.max(ee):.3f} | {max(x.delay for x in fr):.3f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--horses", type=int, default=300)
    ap.add_argument("--size", type=int, nargs=2, default=[480, 270])
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--poe", type=float, default=1.0)
    ap.add_argument("--blur", type=float, default=2.0, help="sigma, pixels, of the popping measure")
    ap.add_argument("--speed", type=float, default=4.0, help="camera path speed-up (key times divided by it)")
    ap.add_argument("--still", action="store_true", help="freeze the herd: only the camera moves")
    ap.add_argument("--path", choices=("scene", "close"), default="scene",
                    help="camera: the scene's path, or a low dolly into the herd")
    ap.add_argument("--terrain-frames", type=int, default=96)
    ap.add_argument("--terrain-resolution", type=int, default=513)
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--part", choices=("both", "crowd", "terrain"), default="both")
    ap.add_argument("--ss", type=int, default=1, help="supersampling of the crowd's images (1: none)")
    ap.add_argument("--mode", choices=("triangles", "clusters"), default="triangles",
                    help="the crowd's LOD mode: triangle levels (faded) or cluster cuts (geomorphed)")
    a = ap.parse_args(argv)
    if a.frames < 2 or a.horses < 1 or a.n < 2 or not a.speed > 0 or not 1 <= a.ss <= 8:
        ap.error("--frames must be >= 2, --horses >= 1, --n >= 2, --speed > 0, --ss 1..8")
    if a.part in ("both", "crowd"):
        crowd_part(a.frames, a.horses, tuple(a.size), a.n, a.poe, a.blur, a.speed, a.still, a.path, a.mode, a.ss)
    if a.part in ("both", "terrain"):
        terrain_part(a.terrain_frames, (1280, 720), a.n, a.tau, a.terrain_resolution)


if __name__ == "__main__":
    main()
