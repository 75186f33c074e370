"""glTF 2.0 export of animated characters.

Export (:func:`save_glb`) writes a :class:`sim.character.SkinnedCharacter` or
:class:`sim.character.KeyframedCharacter` as a binary glTF that
:func:`sim.gltf.load.load_gltf` reads back: the binary buffer and its
accessors are laid out here (:class:`_Writer`), pygltflib writes the GLB
container.

Notes
-----
Writes glTF 2.0 (specification 2.0.1): §3.6 buffers, buffer views and
accessors (4-byte aligned, little-endian), §3.7.2 meshes and morph targets,
§3.7.3 skins, §3.11 animations and chapter 4 (GLB). ``extras.loop`` and
``extras.duration`` of each animation record what glTF has no field for.

A skinned mesh's morph targets (:class:`sim.mesh.MorphTargets`) are written as
POSITION/NORMAL targets of its primitive over the glTF base (the mesh at
weights 0), with ``mesh.weights`` the default weights and
``mesh.extras.targetNames`` their names; each clip's ``"weights"`` channels
become one weights channel of the mesh node: exactly when they share their key
times and interpolation, otherwise as one LINEAR channel sampled at the union
of their key times (exact for LINEAR channels and constant ones; STEP and
CUBICSPLINE values between keys are then approximated).
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from sim import math3d
from sim.character import KeyframedCharacter, SkinnedCharacter
from sim.errors import AssetError
from sim.gltf.container import _NCOMP


class _Writer:
    """Accumulates a binary buffer, bufferViews and accessors (4-byte aligned)."""

    def __init__(self):
        self.blob = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, arr: np.ndarray, typ: str, target: int | None = None, minmax: bool = False) -> int:
        arr = np.ascontiguousarray(arr)
        ct = {np.dtype("float32"): 5126, np.dtype("uint32"): 5125, np.dtype("uint16"): 5123, np.dtype("uint8"): 5121}[arr.dtype]
        while len(self.blob) % 4:
            self.blob.append(0)
        view = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": arr.nbytes}
        if target is not None:
            view["target"] = target
        self.blob += arr.astype(arr.dtype.newbyteorder("<")).tobytes()
        self.views.append(view)
        nc = _NCOMP[typ]
        acc = {"bufferView": len(self.views) - 1, "componentType": ct, "count": int(arr.size // nc), "type": typ}
        if minmax:
            a2 = arr.reshape(-1, nc)
            acc["min"] = [float(x) for x in a2.min(0)]
            acc["max"] = [float(x) for x in a2.max(0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _f32(a) -> np.ndarray:
    a = np.asarray(a, np.float32)
    if not np.all(np.isfinite(a)):
        raise AssetError("save_glb: refusing to write NaN or infinite values")
    return a


def save_glb(character, path) -> None:
    """Write a character as a binary glTF 2.0 file, atomically.

    Parameters
    ----------
    character : SkinnedCharacter or KeyframedCharacter
        Skinned: mesh with NORMAL, COLOR_0 (vec4 float), JOINTS_0 (ushort),
        WEIGHTS_0 (float), a material with ``doubleSided`` true when the mesh is
        double-sided (none otherwise: glTF's default is single-sided), a skin with inverse bind matrices, one node per
        joint with its rest TRS (plus a parent node holding
        ``root_transform`` when it is not the identity), and one animation per
        clip keeping its interpolation. Keyframed: keyframe 0 is the base
        mesh and every further keyframe (of every animation) one morph target
        (POSITION/NORMAL/COLOR_0 deltas); each animation is a weights channel
        with one-hot weights at the keyframe times, closed by a key equal to
        the first at ``duration`` when it loops. ``extras.loop`` records the
        loop flag.
    path : str or Path
        Written via a temporary file in the same folder and ``os.replace``.

    Raises
    ------
    AssetError
        Keyframes of different topology (morph targets need one vertex and
        index list), an empty mesh, or non-finite values.
    """
    import pygltflib

    path = Path(path)
    w = _Writer()
    if character.kind == "skinned":
        gl = _export_skinned(character, w)
    elif character.kind == "keyframed":
        gl = _export_keyframed(character, w, path)
    else:
        raise AssetError(f"{path.name}: cannot export a character of kind {character.kind!r}")
    gl["asset"] = {"version": "2.0", "generator": "crowd-sandbox sim.gltf.write"}
    gl["scene"] = 0
    gl["buffers"] = [{"byteLength": len(w.blob)}]
    gl["bufferViews"] = w.views
    gl["accessors"] = w.accessors
    doc = pygltflib.GLTF2.from_dict(gl)
    doc.set_binary_blob(bytes(w.blob))
    data = b"".join(doc.save_to_bytes())
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _mesh_primitive(w: _Writer, positions, normals, colors, indices, extra: dict | None = None) -> dict:
    attrs = {
        "POSITION": w.add(_f32(positions), "VEC3", 34962, minmax=True),
        "NORMAL": w.add(_f32(normals), "VEC3", 34962),
        "COLOR_0": w.add(_f32(colors), "VEC4", 34962),
    }
    attrs.update(extra or {})
    return {"attributes": attrs, "indices": w.add(np.asarray(indices, np.uint32).ravel(), "SCALAR", 34963), "mode": 4}


def _export_skinned(ch: SkinnedCharacter, w: _Writer) -> dict:
    m, sk = ch.mesh, ch.skeleton
    if m.n_vertices == 0 or m.n_triangles == 0:
        raise AssetError(f"save_glb: character {ch.name!r} has an empty mesh")
    if not m.is_skinned:
        raise AssetError(f"save_glb: character {ch.name!r} mesh has no joints/weights")
    J = sk.n_joints
    nodes = []
    for j in range(J):
        nodes.append({
            "name": str(sk.names[j]),
            "translation": [float(x) for x in sk.rest_translation[j]],
            "rotation": [float(x) for x in math3d.quat_normalize(sk.rest_rotation[j])],
            "scale": [float(x) for x in sk.rest_scale[j]],
        })
    for j in range(J):
        p = int(sk.parents[j])
        if p >= 0:
            nodes[p].setdefault("children", []).append(j)
    roots = [j for j in range(J) if sk.parents[j] < 0]
    scene_nodes = []
    rt = np.eye(4) if sk.root_transform is None else np.asarray(sk.root_transform, np.float64)
    if np.array_equal(rt, np.eye(4)):
        scene_nodes += roots
    else:
        nodes.append({"name": "root_transform", "matrix": [float(x) for x in rt.T.ravel()], "children": roots})
        scene_nodes.append(len(nodes) - 1)
    extra = {
        "JOINTS_0": w.add(np.asarray(m.joints, np.uint16), "VEC4", 34962),
        "WEIGHTS_0": w.add(_f32(m.weights), "VEC4", 34962),
    }
    mt = m.morph
    pos, nrm = np.asarray(m.positions, np.float64), np.asarray(m.ensure_normals(), np.float64)
    if mt is not None:  # the glTF base is the mesh at weights 0
        d = np.asarray(mt.default_weights, np.float64)
        pos = pos - np.einsum("m,mvc->vc", d, np.asarray(mt.positions, np.float64))
        nrm = nrm - np.einsum("m,mvc->vc", d, np.asarray(mt.normals, np.float64))
    prim = _mesh_primitive(w, pos, nrm, m.vertex_colors(), m.indices, extra)
    if mt is not None and mt.n_targets:
        prim["targets"] = [{"POSITION": w.add(_f32(mt.positions[k]), "VEC3", 34962, minmax=True),
                            "NORMAL": w.add(_f32(mt.normals[k]), "VEC3", 34962)} for k in range(mt.n_targets)]
    ib = w.add(_f32(np.asarray(sk.inverse_bind, np.float64).transpose(0, 2, 1)).reshape(J, 16), "MAT4")
    nodes.append({"name": str(ch.name), "mesh": 0, "skin": 0})
    mesh_node = len(nodes) - 1
    scene_nodes.append(mesh_node)
    skin = {"joints": list(range(J)), "inverseBindMatrices": ib}
    if len(roots) == 1:
        skin["skeleton"] = roots[0]
    anims = []
    for name, clip in ch.clips.items():
        samplers, channels = [], []
        for c in clip.channels:
            if c.path not in ("translation", "rotation", "scale"):
                continue
            t = _f32(c.times).ravel()
            v = np.asarray(c.values, np.float64)
            nc = 4 if c.path == "rotation" else 3
            v = v.reshape(-1, nc)
            samplers.append({
                "input": w.add(t, "SCALAR", minmax=True),
                "output": w.add(_f32(v), "VEC4" if nc == 4 else "VEC3"),
                "interpolation": c.interpolation,
            })
            channels.append({"sampler": len(samplers) - 1, "target": {"node": int(c.joint), "path": c.path}})
        wt = _weights_sampler(clip, mt)
        if wt is not None:
            t, v, interp = wt
            samplers.append({"input": w.add(_f32(t), "SCALAR", minmax=True), "output": w.add(_f32(v).ravel(), "SCALAR"),
                             "interpolation": interp})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": mesh_node, "path": "weights"}})
        if channels:
            anims.append({"name": str(name), "samplers": samplers, "channels": channels,
                          "extras": {"loop": bool(clip.loop), "duration": float(clip.duration)}})
    gmesh = {"name": str(ch.name), "primitives": [prim]}
    if mt is not None and mt.n_targets:
        gmesh["weights"] = [float(x) for x in mt.default_weights]
        gmesh["extras"] = {"targetNames": [str(x) for x in mt.names]} if len(mt.names) == mt.n_targets else {}
    gl = {
        "scenes": [{"nodes": scene_nodes}],
        "nodes": nodes,
        "meshes": [gmesh],
        "skins": [skin],
    }
    if getattr(m, "double_sided", True):  # glTF's default material is single-sided (§3.9.5)
        prim["material"] = 0
        gl["materials"] = [{"name": "double_sided", "doubleSided": True}]
    if anims:
        gl["animations"] = anims
    return gl


def _weights_sampler(clip, mt):
    """(times (K,), values (K, M) or (K, 3, M), interpolation) of a clip's morph
    weights as one glTF channel over all M targets, or None (module Notes)."""
    chans = [c for c in clip.channels if c.path == "weights"]
    if mt is None or not mt.n_targets or not chans:
        return None
    M = mt.n_targets
    t0, interp = np.asarray(chans[0].times, np.float64), chans[0].interpolation
    if all(c.interpolation == interp and np.array_equal(np.asarray(c.times, np.float64), t0) for c in chans):
        # one key list: the columns side by side (default weights, zero tangents where no channel drives)
        K = t0.shape[0]
        cubic = interp == "CUBICSPLINE"
        v = np.zeros((K, 3, M)) if cubic else np.zeros((K, M))
        (v[:, 1] if cubic else v)[:] = np.asarray(mt.default_weights, np.float64)
        for c in chans:
            a, x = int(c.joint), np.asarray(c.values, np.float64)
            v[..., a:a + x.shape[-1]] = x.reshape(v.shape[:-1] + (x.shape[-1],))
        return t0, v, interp
    times = np.unique(np.concatenate([np.asarray(x.times, np.float64) for x in chans]))
    only = type(clip)(clip.name, float(times[-1]) + 1.0, chans, loop=False)  # sampling without wrapping
    return times, only.morph_weights(mt, times), "LINEAR"


def _export_keyframed(ch: KeyframedCharacter, w: _Writer, path: Path) -> dict:
    if not ch.animations:
        raise AssetError(f"{path.name}: character {ch.name!r} has no keyframe animations to export")
    anims = list(ch.animations.values())
    base = anims[0].keyframes[0]
    idx0 = np.asarray(base.indices)
    frames = []  # (animation index, keyframe index, Keyframe) for morph targets
    for ai, an in enumerate(anims):
        for k, kf in enumerate(an.keyframes):
            if np.asarray(kf.positions).shape != np.asarray(base.positions).shape or not np.array_equal(np.asarray(kf.indices), idx0):
                raise AssetError(
                    f"{path.name}: animation {an.name!r} keyframe {k} has a different topology "
                    f"({len(kf.positions)} vertices, {len(kf.indices)} triangles vs {len(base.positions)}, {len(base.indices)}); "
                    "morph-target export needs every keyframe to share vertices and indices"
                )
            if ai == 0 and k == 0:
                continue
            frames.append((ai, k, kf))
    b_p, b_n, b_c = (np.asarray(x, np.float64) for x in (base.positions, base.normals, base.colors))
    colors_vary = any(not np.array_equal(np.asarray(kf.colors), np.asarray(base.colors)) for _, _, kf in frames)
    prim = _mesh_primitive(w, b_p, b_n, b_c, idx0)
    targets = []
    for _, _, kf in frames:
        t = {
            "POSITION": w.add(_f32(np.asarray(kf.positions, np.float64) - b_p), "VEC3", 34962, minmax=True),
            "NORMAL": w.add(_f32(np.asarray(kf.normals, np.float64) - b_n), "VEC3", 34962),
        }
        if colors_vary:
            t["COLOR_0"] = w.add(_f32(np.asarray(kf.colors, np.float64) - b_c), "VEC4", 34962)
        targets.append(t)
    if targets:
        prim["targets"] = targets
    nt = len(targets)
    slot = {(ai, k): s for s, (ai, k, _) in enumerate(frames)}
    gl_anims = []
    for ai, an in enumerate(anims):
        if nt == 0:
            break
        times = list(np.asarray(an.times, np.float64))
        rows = []
        for k in range(len(an.keyframes)):
            r = np.zeros(nt)
            if (ai, k) in slot:
                r[slot[(ai, k)]] = 1.0
            rows.append(r)
        end = times[0] + float(an.duration)  # the loop closes at times[0] + duration
        if an.loop and end > times[-1]:
            times.append(end)
            rows.append(rows[0].copy())
        samplers = [{
            "input": w.add(_f32(times), "SCALAR", minmax=True),
            "output": w.add(_f32(np.concatenate(rows)), "SCALAR"),
            "interpolation": "LINEAR",
        }]
        gl_anims.append({"name": str(an.name), "samplers": samplers,
                         "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
                         "extras": {"loop": bool(an.loop), "duration": float(an.duration)}})
    mesh = {"name": str(ch.name), "primitives": [prim]}
    if nt:
        mesh["weights"] = [0.0] * nt
    gl = {"scenes": [{"nodes": [0]}], "nodes": [{"name": str(ch.name), "mesh": 0}], "meshes": [mesh]}
    if gl_anims:
        gl["animations"] = gl_anims
    return gl
