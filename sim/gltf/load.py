"""glTF 2.0 import of animated characters.

Import (:func:`load_gltf`) turns the default scene of a ``.glb`` or ``.gltf``
file into one :class:`sim.character.SkinnedCharacter` (skins, node TRS
animation, rigid parts) or :class:`sim.character.KeyframedCharacter` (morph
target animation, one keyframe per key time). :func:`sim.gltf.write.save_glb`
writes either kind back.

Notes
-----
Follows the Khronos glTF 2.0 specification (version 2.0.1), through the
modules of :mod:`sim.gltf`; here §3.7.2.2 morph targets (keyframes, or kept
as :class:`sim.mesh.MorphTargets` on a skinned character) and §3.7.3
skins (joint matrix = global joint transform x inverse bind matrix; the
skinned mesh node's own transform is ignored), with the animations of §3.11.

Where it departs from a full viewer:

- All meshes of the scene are merged into one :class:`sim.mesh.Mesh`. Several
  skins become one skeleton over the union of their joints. Nodes that are not
  joints but lie between joints, carry a rigid (non-skinned) mesh, or are
  animated ancestors of joints are added as extra joints; a rigid mesh is
  bound with weight 1 to its node's joint, so node animation still plays.
- Textures are not kept, but sampled into the vertex colours
  (:mod:`sim.gltf.primitives`).
- Morph targets on a skinned (or node-animated) model are kept
  (:class:`sim.mesh.MorphTargets`: POSITION and NORMAL deltas of every
  target, merged over the meshes, the mesh at its default weights) and their
  ``weights`` animations become ``"weights"`` channels of the clips
  (:class:`sim.clip.Channel`, first target in ``joint``), played before
  skinning (``sim.skinning.skin_morph``). COLOR_0 deltas are applied at the
  default weights only; a mesh without NORMAL keeps its computed normals
  unmorphed. Target names come from ``mesh.extras.targetNames`` (prefixed
  with the node name when several nodes carry targets).
- More than four influences (``JOINTS_1``/``WEIGHTS_1``) keep the four
  largest, renormalised. When the skeleton's roots hang below different
  parent nodes, every ancestor becomes a joint (``root_transform`` = identity).
- Skin weights are normalised to sum to 1; rows that summed to something else
  in the file (beyond :data:`sim.skin_weights.SUM_TOLERANCE`) are counted in
  the character's ``notes`` ("skin weights normalised on N vertices (sums
  1.8)"), which ``crowd info`` prints.
- A model without animation (a statue, a prop) is a character all the same:
  a skinned one gets one constant clip ``"rest"`` holding the rest pose
  (:func:`sim.clip.rest_clip`), a morph-target one a still keyframe of the same
  name, so every LOD mode draws it in its rest pose (noted in ``notes``).

Every problem with the input raises :class:`sim.errors.AssetError` with one
sentence naming the file and the offending element.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from sim import math3d
from sim.character import KeyframedCharacter, SkinnedCharacter
from sim.clip import REST_CLIP_NAME, REST_CLIP_SECONDS, Channel, Clip, rest_clip
from sim.errors import AssetError
from sim.gltf.animation import _read_sampler, _sample_channel
from sim.gltf.container import _Doc, _is_int
from sim.gltf.primitives import _bake, _bake_deltas, _finish_normals, _Prim
from sim.gltf.scene_graph import _Graph
from sim.mesh import Mesh, MorphTargets
from sim.skeleton import Skeleton
from sim.skin_weights import SUM_TOLERANCE

#: Two morph weight vectors closer than this are "the same key" (closed loops).
GLTF_LOOP_TOL = 1e-6


def load_gltf(path) -> SkinnedCharacter | KeyframedCharacter:
    """Load the default scene of a glTF 2.0 file as one character.

    Parameters
    ----------
    path : str or Path
        ``.glb`` or ``.gltf`` (buffers embedded as base64 data URIs, in the GLB
        binary chunk, or in files relative to the ``.gltf``).

    Returns
    -------
    SkinnedCharacter
        When the scene has a skin, node TRS animation, or no morph targets.
        ``mesh`` merges every triangle primitive (positions (V,3) float32,
        normals, colours (V,4), joints (V,4) uint16, weights (V,4) float32
        rows summing to 1); ``skeleton`` joints are topologically ordered;
        ``clips`` maps animation name (or ``anim{i}``) to :class:`sim.clip.Clip`.
    KeyframedCharacter
        When unskinned meshes carry morph targets: one
        :class:`sim.keyframes.KeyframeAnimation` per morph animation, with a
        keyframe per key time (a single static keyframe when not animated).
        Animations loop unless ``extras.loop`` is false (written by
        :func:`save_glb`); a final key equal to the first closes the loop and
        is dropped, otherwise the loop closes over one mean key interval.

    Raises
    ------
    AssetError
        For any malformed or unsupported input; the message names the file
        and the offending element.
    """
    path = Path(path)
    doc = _Doc(path)
    try:
        return _load(doc)
    except AssetError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as e:
        # schema violations our explicit checks did not anticipate
        raise AssetError(f"{doc.name}: {doc.ctx}: malformed glTF element ({type(e).__name__}: {e})") from None


def _load(doc: _Doc):
    g = _Graph(doc)
    in_scene = set(g.scene_nodes)
    mesh_nodes = [i for i in g.scene_nodes if "mesh" in doc.item("nodes", i)]
    if not mesh_nodes:
        doc.fail("the default scene has no mesh")
    prims: dict[int, list[_Prim]] = {}
    for ni in mesh_nodes:
        nd = doc.item("nodes", ni)
        mi = nd["mesh"]
        m = doc.item("meshes", mi, f"nodes[{ni}]")
        plist = m.get("primitives") or []
        if not plist:
            doc.fail(f"meshes[{mi}] has no primitives")
        weights = nd.get("weights", m.get("weights"))
        prims[ni] = [_Prim(doc, mi, pi, p, weights) for pi, p in enumerate(plist)]

    skinned_nodes = [ni for ni in mesh_nodes if "skin" in doc.item("nodes", ni)]
    for ni in skinned_nodes:
        doc.item("skins", doc.item("nodes", ni)["skin"], f"nodes[{ni}].skin")
    anims = doc.items("animations")
    trs_targets, weight_targets = set(), set()
    for ai, a in enumerate(anims):
        doc.ctx = f"animations[{ai}]"
        if not isinstance(a, dict):
            doc.fail(f"animations[{ai}] is not an object")
        for ci, ch in enumerate(a.get("channels") or []):
            tgt = ch.get("target") or {}
            node = tgt.get("node")
            if node is None:
                continue
            if not _is_int(node) or not 0 <= node < g.n:
                doc.fail(f"animations[{ai}].channels[{ci}]: target node {node!r} does not exist ({g.n} nodes)")
            p = tgt.get("path")
            if p in ("translation", "rotation", "scale"):
                trs_targets.add(node)
            elif p == "weights":
                weight_targets.add(node)
    morph_nodes = [ni for ni in mesh_nodes if any(p.targets for p in prims[ni])]

    has_trs = bool(trs_targets & in_scene)
    morph_animated = bool(weight_targets & set(morph_nodes))
    # keyframed: unskinned morph meshes, animated by weights (or not animated at all)
    if not skinned_nodes and morph_nodes and (morph_animated or not has_trs):
        if has_trs:
            warnings.warn(f"{doc.name}: node TRS animations are ignored in a morph-target (keyframed) character", stacklevel=3)
        return _load_keyframed(doc, g, mesh_nodes, prims, morph_nodes)
    return _load_skinned(doc, g, mesh_nodes, skinned_nodes, prims, trs_targets & in_scene, morph_nodes)


def _target_slots(doc: _Doc, prims, morph_nodes, notes: list | None = None) -> tuple[dict, list]:
    """First merged target index of every morph node, and the merged target names.

    glTF 2.0 §3.7.2.2 asks every primitive of a mesh for the same number of targets; a file that breaks this is
    read leniently: the missing targets of the shorter primitives are zero deltas (noted in ``notes``)."""
    first, names = {}, []
    for ni in morph_nodes:
        nd = doc.item("nodes", ni)
        counts = {len(p.targets) for p in prims[ni]}
        if len(counts) != 1 and notes is not None:
            notes.append(f"meshes[{nd['mesh']}]: primitives have different numbers of morph targets "
                         f"({', '.join(map(str, sorted(counts)))}); the missing ones are read as zero deltas")
        nt = max(counts)
        m = doc.item("meshes", nd["mesh"])
        ex = m.get("extras") if isinstance(m.get("extras"), dict) else {}
        tn = ex.get("targetNames")
        if not (isinstance(tn, list) and len(tn) == nt and all(isinstance(x, str) for x in tn)):
            tn = [f"target{k}" for k in range(nt)]
        prefix = f"{nd.get('name') or f'node{ni}'}." if len(morph_nodes) > 1 else ""
        first[ni] = len(names)
        names.extend(prefix + x for x in tn)
    return first, names


def _load_skinned(doc, g: _Graph, mesh_nodes, skinned_nodes, prims, animated, morph_nodes=()):
    # ---- joint node set
    skins_used = sorted({doc.item("nodes", ni)["skin"] for ni in skinned_nodes})
    skin_joints: dict[int, list[int]] = {}
    S: list[int] = []  # ordered set of joint nodes (skin order first)
    for si in skins_used:
        doc.ctx = f"skins[{si}]"
        sk = doc.item("skins", si, "nodes[].skin")
        js = sk.get("joints") or []
        if not js:
            doc.fail(f"skins[{si}] has no joints")
        for j in js:
            if not _is_int(j) or not 0 <= j < g.n:
                doc.fail(f"skins[{si}].joints: node {j!r} does not exist ({g.n} nodes)")
        skin_joints[si] = js
        S.extend(j for j in js if j not in S)
    rigid_nodes = [ni for ni in mesh_nodes if ni not in skinned_nodes]
    S.extend(ni for ni in rigid_nodes if ni not in S)

    def closure():
        changed = True
        while changed:
            changed = False
            inS = set(S)
            for j in list(S):
                anc = g.ancestors(j)
                hit = next((k for k, a in enumerate(anc) if a in inS), None)
                if hit is not None:
                    add = anc[:hit]  # nodes between j and its nearest joint ancestor
                else:
                    an = [k for k, a in enumerate(anc) if a in animated]
                    add = anc[: an[-1] + 1] if an else []  # up to the highest animated ancestor
                for a in add:
                    if a not in inS:
                        S.append(a)
                        inS.add(a)
                        changed = True

    closure()
    roots = [j for j in S if g.parent[j] not in set(S)]
    if len({int(g.parent[r]) for r in roots}) > 1:
        for r in roots:
            S.extend(a for a in g.ancestors(r) if a not in S)
        closure()
    # ---- stable topological order (parents before children)
    inS = set(S)
    order: list[int] = []
    placed = set()

    def place(j):
        p = int(g.parent[j])
        if p in inS and p not in placed:
            place(p)
        if j not in placed:
            placed.add(j)
            order.append(j)

    for j in S:
        place(j)
    jindex = {nd: k for k, nd in enumerate(order)}
    J = len(order)
    parents = np.array([jindex.get(int(g.parent[nd]), -1) for nd in order], np.int32)
    root_parent = int(g.parent[order[0]])
    root_transform = g.world[root_parent].copy() if root_parent >= 0 else np.eye(4)
    names = []
    used_names: set = set()
    for nd in order:
        names.append(_unique_name(str(doc.item("nodes", nd).get("name") or f"node{nd}"), used_names))
    rt = np.array([g.trs[nd][0] for nd in order], np.float64)
    rr = np.array([g.trs[nd][1] for nd in order], np.float64)
    rs = np.array([g.trs[nd][2] for nd in order], np.float64)
    # inverse binds: skin data where given, else the rest pose (world inverse)
    ib = math3d.invert_affine(np.array([g.world[nd] for nd in order]))
    have_ib = np.zeros(J, bool)
    for si in skins_used:
        sk = doc.item("skins", si)
        js = skin_joints[si]
        if "inverseBindMatrices" in sk:
            m = doc.floats(sk["inverseBindMatrices"], f"skins[{si}].inverseBindMatrices", (16,))
            if m.shape[0] < len(js):
                doc.fail(f"skins[{si}].inverseBindMatrices: {m.shape[0]} matrices for {len(js)} joints")
            m = m[: len(js)].reshape(-1, 4, 4).transpose(0, 2, 1)
        else:
            m = np.broadcast_to(np.eye(4), (len(js), 4, 4))
        for k, nd in enumerate(js):
            jk = jindex[nd]
            if have_ib[jk] and not np.allclose(ib[jk], m[k], atol=1e-5):
                warnings.warn(f"{doc.name}: joint nodes[{nd}] has different inverse bind matrices in two skins; using the first", stacklevel=4)
                continue
            ib[jk] = m[k]
            have_ib[jk] = True
    skeleton = Skeleton(
        names=names, parents=parents, rest_translation=rt, rest_rotation=rr, rest_scale=rs,
        inverse_bind=ib, root_transform=root_transform,
    )
    # ---- merged mesh (morph targets: deltas of every merged target over all vertices)
    target_notes: list = []
    tfirst, tnames = _target_slots(doc, prims, morph_nodes, target_notes)
    DP, DN, DW = [], [], np.zeros(len(tnames))
    P, N, C, T, JO, W, MAT = [], [], [], [], [], [], []
    nv = 0
    zero_total = 0
    off_count, off_lo, off_hi = 0, np.inf, -np.inf
    for ni in mesh_nodes:
        nd = doc.item("nodes", ni)
        for pr in prims[ni]:
            p, n, c = pr.morphed(None)
            tri = pr.tri
            dp = dn = None
            if ni in tfirst:
                dp, dn = pr.deltas()
                DW[tfirst[ni]:tfirst[ni] + dp.shape[0]] = pr.default_weights
            if ni in skinned_nodes:
                si = nd["skin"]
                js = skin_joints[si]
                if pr.joints is None or pr.weights is None:
                    doc.fail(f"{pr.where}: skinned by skins[{si}] but has no JOINTS_0/WEIGHTS_0")
                if pr.joints.size and pr.joints.max() >= len(js):
                    doc.fail(f"{pr.where}: JOINTS_0 index {int(pr.joints.max())} out of range for skins[{si}] with {len(js)} joints")
                remap = np.array([jindex[x] for x in js], np.int64)
                jj = remap[pr.joints]
                ww = pr.weights
                fallback = jindex.get(ni, 0)
            else:
                # rigid part: bind to its own joint so G_j @ IB_j @ v_bind = G_j @ v_local
                jk = jindex[ni]
                bind = math3d.invert_affine(ib[jk])
                p, n, tri = _bake(p, n, tri, bind)
                if dp is not None:
                    dp, dn = _bake_deltas(dp, dn, bind)
                jj = np.zeros((p.shape[0], 4), np.int64)
                jj[:, 0] = jk
                ww = np.zeros((p.shape[0], 4))
                ww[:, 0] = 1.0
                fallback = jk
            # weights that do not sum to 1 in the file (all influences, before keeping four): normalised below
            s = ww.sum(1)
            off = (s > 1e-12) & (np.abs(s - 1.0) > SUM_TOLERANCE)
            if np.any(off):
                off_count += int(off.sum())
                off_lo, off_hi = min(off_lo, float(s[off].min())), max(off_hi, float(s[off].max()))
            # best four influences, renormalised
            if jj.shape[1] > 4:
                o = np.argsort(-ww, axis=1, kind="stable")[:, :4]
                jj, ww = np.take_along_axis(jj, o, 1), np.take_along_axis(ww, o, 1)
            s = ww.sum(1)
            zero = ~(s > 1e-12)
            if np.any(zero):
                zero_total += int(zero.sum())
                ww[zero] = (1.0, 0.0, 0.0, 0.0)
                jj[zero] = (fallback, 0, 0, 0)
                s = ww.sum(1)
            ww = ww / s[:, None]
            P.append(p)
            N.append(_finish_normals(p, n, tri))
            C.append(c)
            MAT.append(np.full(p.shape[0], -1 if pr.material is None else int(pr.material), np.int64))
            T.append(tri + nv)
            JO.append(jj)
            W.append(ww)
            if tnames:
                DP.append(np.zeros((len(tnames), p.shape[0], 3)))
                DN.append(np.zeros((len(tnames), p.shape[0], 3)))
                if dp is not None:
                    DP[-1][tfirst[ni]:tfirst[ni] + dp.shape[0]] = dp
                    DN[-1][tfirst[ni]:tfirst[ni] + dp.shape[0]] = dn
            nv += p.shape[0]
    if zero_total:
        warnings.warn(f"{doc.name}: {zero_total} vertices have all-zero skin weights; bound to their mesh node's joint (or joint 0)", stacklevel=3)
    notes = list(target_notes)
    if off_count:
        sums = f"{off_lo:.3g}" if off_hi - off_lo < 0.005 else f"{off_lo:.3g} to {off_hi:.3g}"
        notes.append(f"skin weights normalised on {off_count} vertices (sums {sums})")
    mesh = Mesh(
        positions=np.concatenate(P).astype(np.float32),
        indices=np.concatenate(T).astype(np.uint32).reshape(-1, 3),
        normals=np.concatenate(N).astype(np.float32),
        colors=np.concatenate(C).astype(np.float32),
        joints=np.concatenate(JO).astype(np.uint16),
        weights=np.concatenate(W).astype(np.float32),
        double_sided=any(pr.double_sided for ni in mesh_nodes for pr in prims[ni]),
    )
    if tnames:
        mesh.morph = MorphTargets(positions=np.concatenate(DP, 1).astype(np.float32),
                                  normals=np.concatenate(DN, 1).astype(np.float32), default_weights=DW,
                                  names=tnames)
    # ---- clips
    clips = {}
    used: set = set()
    for ai, a in enumerate(doc.items("animations")):
        doc.ctx = f"animations[{ai}]"
        channels = []
        tmax = 0.0
        for ci, ch in enumerate(a.get("channels") or []):
            tgt = ch.get("target") or {}
            path_, node = tgt.get("path"), tgt.get("node")
            if path_ == "weights" and node in tfirst:
                t, v, interp = _read_sampler(doc, ai, a, ch.get("sampler"), None)
                nt = max(len(p.targets) for p in prims[node])
                if v.shape[-1] != nt:
                    doc.fail(f"animations[{ai}].channels[{ci}]: {v.shape[-1]} weights per key, "
                             f"meshes[{doc.item('nodes', node)['mesh']}] has {nt} morph targets")
                channels.append(Channel(joint=tfirst[node], path="weights", times=t, values=v, interpolation=interp))
                tmax = max(tmax, float(t[-1]))
                continue
            if path_ not in ("translation", "rotation", "scale") or node not in jindex:
                continue  # a node that affects nothing we draw
            nc = 4 if path_ == "rotation" else 3
            t, v, interp = _read_sampler(doc, ai, a, ch.get("sampler"), (nc,))
            if v.shape[-1] != nc:
                doc.fail(f"animations[{ai}].channels[{ci}]: {path_} output has {v.shape[-1]} components per key, expected {nc}")
            if path_ == "rotation" and interp != "CUBICSPLINE":
                v = math3d.quat_normalize(v)
            channels.append(Channel(joint=jindex[node], path=path_, times=t, values=v, interpolation=interp))
            tmax = max(tmax, float(t[-1]))
        if not channels:
            continue
        name = _unique_name(str(a.get("name") or f"anim{ai}"), used)
        extras = a.get("extras") if isinstance(a.get("extras"), dict) else {}
        loop = bool(extras.get("loop", True))
        duration = tmax
        d = extras.get("duration")  # written by save_glb; never shorter than the keys
        if isinstance(d, (int, float)) and np.isfinite(d) and d >= tmax:
            duration = float(d)
        clips[name] = Clip(name=name, duration=duration if duration > 0 else 1.0 / 30.0, channels=channels, loop=loop)
    if not clips:
        # a statue or a prop: drawn in its rest pose by every LOD mode through one constant clip (sim.clip.rest_clip)
        clips[REST_CLIP_NAME] = rest_clip(skeleton)
        notes.append(f"no animation: one constant clip {REST_CLIP_NAME!r} ({REST_CLIP_SECONDS:g} s) holds the rest pose")
    mat = np.concatenate(MAT)  # each vertex's material: regions "material:N" of the colour variation
    regions = {f"material:{m}": mat == m for m in np.unique(mat) if m >= 0}
    return SkinnedCharacter(name=doc.path.stem, mesh=mesh, skeleton=skeleton, clips=clips, source=str(doc.path),
                            notes=notes, regions=regions)


def _load_keyframed(doc, g: _Graph, mesh_nodes, prims, morph_nodes):
    from sim import keyframes

    def build(weights_at: dict[int, np.ndarray] | None):
        P, N, C, T = [], [], [], []
        nv = 0
        for ni in mesh_nodes:
            w = None if weights_at is None else weights_at.get(ni)
            for pr in prims[ni]:
                p, n, c = pr.morphed(w)
                p, n, tri = _bake(p, n, pr.tri, g.world[ni])
                P.append(p)
                N.append(_finish_normals(p, n, tri))
                C.append(c)
                T.append(tri + nv)
                nv += p.shape[0]
        return Mesh(
            positions=np.concatenate(P).astype(np.float32),
            indices=np.concatenate(T).astype(np.uint32).reshape(-1, 3),
            normals=np.concatenate(N).astype(np.float32),
            colors=np.concatenate(C).astype(np.float32),
            double_sided=any(pr.double_sided for ni in mesh_nodes for pr in prims[ni]),
        )

    animations = {}
    used: set = set()
    morph_set = set(morph_nodes)
    for ai, a in enumerate(doc.items("animations")):
        doc.ctx = f"animations[{ai}]"
        chans = {}
        for ci, ch in enumerate(a.get("channels") or []):
            tgt = ch.get("target") or {}
            if tgt.get("path") != "weights" or tgt.get("node") not in morph_set:
                continue
            ni = tgt["node"]
            t, v, interp = _read_sampler(doc, ai, a, ch.get("sampler"), None)
            nt = len(prims[ni][0].targets)
            if v.shape[-1] != nt:
                doc.fail(f"animations[{ai}].channels[{ci}]: {v.shape[-1]} weights per key, meshes[{doc.item('nodes', ni)['mesh']}] has {nt} morph targets")
            chans[ni] = (t, v, interp)
        if not chans:
            continue
        times = np.unique(np.concatenate([c[0] for c in chans.values()]))
        sampled = {ni: _sample_channel(t, v, interp, times) for ni, (t, v, interp) in chans.items()}
        extras = a.get("extras") if isinstance(a.get("extras"), dict) else {}
        closed = times.size > 1 and all(np.max(np.abs(w[-1] - w[0])) < GLTF_LOOP_TOL for w in sampled.values())
        loop = bool(extras.get("loop", True))  # glTF has no loop flag; crowds loop (as skinned clips)
        # durations are measured from the first key (sim.keyframes convention)
        d = extras.get("duration")
        if loop and closed:
            duration = float(times[-1] - times[0])
            times = times[:-1]
            sampled = {k: w[:-1] for k, w in sampled.items()}
        elif isinstance(d, (int, float)) and np.isfinite(d) and d >= times[-1] - times[0] and (d > 0 or not loop):
            duration = float(d)
        else:
            duration = None  # from_meshes: the key span (+ one mean interval when looping)
        meshes = [build({ni: w[k] for ni, w in sampled.items()}) for k in range(times.size)]
        name = _unique_name(str(a.get("name") or f"anim{ai}"), used)
        animations[name] = keyframes.from_meshes(name, times, meshes, correspondences=None, loop=loop, duration=duration)
    notes = []
    if not animations:
        name = REST_CLIP_NAME
        animations[name] = keyframes.from_meshes(name, np.array([0.0]), [build(None)], correspondences=None, loop=True,
                                                 duration=REST_CLIP_SECONDS)
        notes.append(f"no animation: one still keyframe {REST_CLIP_NAME!r} ({REST_CLIP_SECONDS:g} s)")
    return KeyframedCharacter(name=doc.path.stem, animations=animations, source=str(doc.path), notes=notes)


def _unique_name(base: str, used: set) -> str:
    name, k = base, 1
    while name in used:
        name = f"{base}.{k}"
        k += 1
    used.add(name)
    return name
