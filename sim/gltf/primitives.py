"""glTF mesh primitives: triangles, colours, skin attributes, morph targets.

:class:`_Prim` reads one primitive in the space of its node; :func:`_bake`
moves it to another space and :func:`_finish_normals` completes its normals.

Notes
-----
Follows §3.7.2 of the glTF 2.0 specification (2.0.1), meshes (TRIANGLES,
TRIANGLE_STRIP and TRIANGLE_FAN primitives; the other modes are refused) and
morph targets (POSITION, NORMAL and COLOR_0 deltas, default weights from the
node or mesh), with the base colour of §3.9.2 (``baseColorFactor``, white
for the default material of §3.9.6) and the textures of §3.8.

Textures are not kept; when a primitive has a base colour texture and
``TEXCOORD_0``, the texture is sampled (nearest texel, Pillow) at every
vertex and multiplied into the vertex colour, so the model stays readable.
``JOINTS_1``/``WEIGHTS_1`` are read next to set 0 (the loader keeps the four
largest influences); negative weights are clipped to 0 with a warning.
"""
from __future__ import annotations

import base64
import io
import urllib.parse
import warnings

import numpy as np

from sim import math3d
from sim.errors import AssetError
from sim.gltf.container import _Doc, _is_int
from sim.mesh import vertex_normals

#: Vertex colour used where a primitive has neither COLOR_0 nor a material
#: (the glTF default material's baseColorFactor).
GLTF_DEFAULT_COLOR = (1.0, 1.0, 1.0, 1.0)

_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 4: "TRIANGLES", 5: "TRIANGLE_STRIP", 6: "TRIANGLE_FAN"}


def _triangles(doc: _Doc, prim: dict, where: str, nverts: int) -> np.ndarray:
    mode = prim.get("mode", 4)
    if not _is_int(mode) or mode not in (4, 5, 6):
        doc.fail(
            f"{where}: primitive mode {mode!r} ({_MODES.get(mode, 'unknown') if _is_int(mode) else 'unknown'}) is not supported; "
            "accepted are TRIANGLES (4), TRIANGLE_STRIP (5) and TRIANGLE_FAN (6)"
        )
    if "indices" in prim:
        ia = doc.accessor(prim["indices"], where)
        if ia.dtype.kind not in "u" or ia.shape[1] != 1:
            doc.fail(f"{where}: accessors[{prim['indices']}] used as indices must be unsigned integer scalars")
        idx = ia[:, 0].astype(np.int64)
        if idx.size and idx.max() >= nverts:
            doc.fail(f"accessors[{prim['indices']}]: index {int(idx.max())} out of range for {nverts} vertices")
    else:
        idx = np.arange(nverts, dtype=np.int64)
    if mode == 4:
        n = idx.size // 3
        tri = idx[: n * 3].reshape(n, 3)
    elif mode == 5:
        k = np.arange(max(idx.size - 2, 0))
        even = (k % 2) == 0
        a = np.where(even, idx[k], idx[k + 1]) if k.size else k
        b = np.where(even, idx[k + 1], idx[k]) if k.size else k
        tri = np.stack([a, b, idx[k + 2]], 1) if k.size else np.zeros((0, 3), np.int64)
    else:
        k = np.arange(1, max(idx.size - 1, 1))
        tri = np.stack([idx[k], idx[k + 1], np.full(k.size, idx[0] if idx.size else 0)], 1) if idx.size >= 3 else np.zeros((0, 3), np.int64)
    return tri


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _texture_colors(doc: _Doc, tex_info: dict, uv: np.ndarray, where: str) -> np.ndarray | None:
    """Nearest-texel sample of a base colour texture at (V, 2) uvs -> (V, 4) linear, or None."""
    try:
        from PIL import Image
    except ImportError:  # optional: colours fall back to baseColorFactor
        return None
    try:
        tex = doc.item("textures", tex_info.get("index", -1), where)
        src = tex.get("source")
        if src is None:
            return None
        img_d = doc.item("images", src, where)
        if "bufferView" in img_d:
            d, s, ln, _ = doc.buffer_view(img_d["bufferView"], where)
            raw = d[s : s + ln]
        elif str(img_d.get("uri", "")).startswith("data:"):
            raw = base64.b64decode(img_d["uri"].partition(",")[2])
        elif "uri" in img_d:
            raw = (doc.path.parent / urllib.parse.unquote(img_d["uri"])).read_bytes()
        else:
            return None
        im = np.asarray(Image.open(io.BytesIO(raw)).convert("RGBA"), np.float64) / 255.0
    except AssetError:
        raise
    except Exception as e:  # unreadable image: colours only, never fatal
        warnings.warn(f"{doc.name}: {where}: base colour texture not readable ({e}); using baseColorFactor", stacklevel=3)
        return None
    h, w = im.shape[:2]
    u = np.mod(np.nan_to_num(uv[:, 0]), 1.0)
    v = np.mod(np.nan_to_num(uv[:, 1]), 1.0)
    x = np.clip((u * w).astype(np.int64), 0, w - 1)
    y = np.clip((v * h).astype(np.int64), 0, h - 1)  # glTF uv origin is the top-left
    c = im[y, x]
    c[:, :3] = _srgb_to_linear(c[:, :3])
    return c


class _Prim:
    """One primitive's vertex data, in the space of its node (not yet baked)."""

    def __init__(self, doc: _Doc, mi: int, pi: int, prim: dict, mesh_weights):
        self.where = where = f"meshes[{mi}].primitives[{pi}]"
        self.material = prim.get("material")  # index, or None (the default material)
        doc.ctx = where
        attrs = prim.get("attributes") or {}
        if "POSITION" not in attrs:
            doc.fail(f"{where}: has no POSITION attribute")
        pos = doc.floats(attrs["POSITION"], f"{where}.attributes.POSITION", (3,), finite=False)
        if not np.all(np.isfinite(pos)):
            doc.fail(f"{where}: accessors[{attrs['POSITION']}] (POSITION) contains NaN or infinite values")
        nv = pos.shape[0]

        def attr(name, ncomp, finite=True):
            if name not in attrs:
                return None
            a = doc.accessor(attrs[name], f"{where}.attributes.{name}")
            if a.shape[0] != nv:
                doc.fail(f"{where}: accessors[{attrs[name]}] ({name}) has {a.shape[0]} elements, POSITION has {nv}")
            if a.shape[1] not in ncomp:
                doc.fail(f"{where}: accessors[{attrs[name]}] ({name}) has {a.shape[1]} components, expected {' or '.join(map(str, ncomp))}")
            if finite and a.dtype.kind == "f" and not np.all(np.isfinite(a)):
                doc.fail(f"{where}: accessors[{attrs[name]}] ({name}) contains NaN or infinite values")
            return a

        self.tri = _triangles(doc, prim, where, nv)
        self.normals = attr("NORMAL", (3,), finite=False)
        if self.normals is not None and not np.all(np.isfinite(self.normals)):
            warnings.warn(f"{doc.name}: {where}: NORMAL has NaN values; normals recomputed", stacklevel=4)
            self.normals = None
        # colours: COLOR_0, else material factor (x texture)
        mat = doc.item("materials", prim["material"], where) if "material" in prim else {}
        # §3.9.5: back faces are culled unless the material is double-sided (the default material is not)
        self.double_sided = mat.get("doubleSided", False) is True
        pbr = mat.get("pbrMetallicRoughness") or {}
        factor = pbr.get("baseColorFactor", GLTF_DEFAULT_COLOR)
        try:
            factor = np.asarray(factor, np.float64).reshape(4)
        except (TypeError, ValueError):
            doc.fail(f"materials[{prim['material']}].pbrMetallicRoughness.baseColorFactor must be 4 numbers, got {factor!r}")
        if not np.all(np.isfinite(factor)):
            doc.fail(f"materials[{prim['material']}].pbrMetallicRoughness.baseColorFactor is not finite")
        col = attr("COLOR_0", (3, 4))
        if col is not None:
            if col.dtype.kind != "f":
                doc.fail(f"{where}: COLOR_0 must be float or normalized unsigned byte/short")
            col = np.concatenate([col, np.ones((nv, 1))], 1) if col.shape[1] == 3 else col
            colors = col * factor
        else:
            colors = np.broadcast_to(factor, (nv, 4)).copy()
            ti = pbr.get("baseColorTexture")
            uv_key = f"TEXCOORD_{(ti or {}).get('texCoord', 0)}"
            if ti and uv_key in attrs:
                uv = attr(uv_key, (2,))
                tc = _texture_colors(doc, ti, uv.astype(np.float64), where) if uv.dtype.kind == "f" else None
                if tc is not None:
                    colors = colors * tc
        self.colors = np.clip(colors, 0.0, 1.0)
        # skin attributes (sets 0 and 1 -> best 4 influences)
        js, ws = [], []
        for k in (0, 1):
            j, w = attr(f"JOINTS_{k}", (4,)), attr(f"WEIGHTS_{k}", (4,))
            if j is None or w is None:
                break
            if j.dtype.kind != "u":
                doc.fail(f"{where}: JOINTS_{k} must be unsigned byte or short, got {j.dtype}")
            js.append(j.astype(np.int64))
            ws.append(w.astype(np.float64))
        if ws:
            neg = np.zeros(nv, bool)
            for w in ws:
                neg |= (w < 0.0).any(axis=1)
            if neg.any():
                warnings.warn(f"{doc.name}: {where}: {int(neg.sum())} vertices have negative skin weights; "
                              "clipped to 0 and renormalised", stacklevel=4)
            ws = [np.clip(w, 0.0, None) for w in ws]
        self.joints = np.concatenate(js, 1) if js else None
        self.weights = np.concatenate(ws, 1) if ws else None
        # morph targets
        self.targets = []
        for ti, tg in enumerate(prim.get("targets") or []):
            d = {}
            for name, nc in (("POSITION", (3,)), ("NORMAL", (3,)), ("COLOR_0", (3, 4))):
                if name in tg:
                    a = doc.floats(tg[name], f"{where}.targets[{ti}].{name}", nc)
                    if a.shape[0] != nv:
                        doc.fail(f"{where}.targets[{ti}]: {name} has {a.shape[0]} elements, POSITION has {nv}")
                    if name == "COLOR_0" and a.shape[1] == 3:
                        a = np.concatenate([a, np.zeros((nv, 1))], 1)
                    d[name] = a
            self.targets.append(d)
        self.positions = pos
        self.default_weights = np.zeros(len(self.targets))
        if mesh_weights is not None:
            try:
                mw = np.asarray(mesh_weights, np.float64).ravel()[: len(self.targets)]
            except (TypeError, ValueError):
                mw = np.full(1, np.nan)
            if not np.all(np.isfinite(mw)):
                doc.fail(f"meshes[{mi}].weights (or its node's weights) must be a list of numbers, got {mesh_weights!r}")
            self.default_weights[: mw.size] = mw

    def deltas(self) -> tuple[np.ndarray, np.ndarray]:
        """(positions, normals) deltas of every morph target, (M, V, 3) float64 each,
        zero where a target has no POSITION / NORMAL (§3.7.2.2)."""
        nv = self.positions.shape[0]
        dp = np.zeros((len(self.targets), nv, 3))
        dn = np.zeros((len(self.targets), nv, 3))
        for k, tg in enumerate(self.targets):
            if "POSITION" in tg:
                dp[k] = tg["POSITION"]
            if "NORMAL" in tg:
                dn[k] = tg["NORMAL"]
        return dp, dn

    def morphed(self, w: np.ndarray | None):
        """(positions, normals or None, colors) with morph weights ``w`` applied."""
        p, n, c = self.positions.copy(), None if self.normals is None else self.normals.copy(), self.colors.copy()
        if w is None:
            w = self.default_weights
        for wi, tg in zip(w, self.targets):
            if wi == 0.0:
                continue
            if "POSITION" in tg:
                p += wi * tg["POSITION"]
            if n is not None and "NORMAL" in tg:
                n += wi * tg["NORMAL"]
            if "COLOR_0" in tg:
                c += wi * tg["COLOR_0"]
        return p, n, np.clip(c, 0.0, 1.0)


def _bake(p, n, tri, world):
    """Transform positions/normals by a node world matrix; flip winding if mirrored."""
    p = p @ world[:3, :3].T + world[:3, 3]
    if n is not None:
        n = math3d.normalize_vectors(n @ math3d.cofactor3(world[:3, :3]).T)
        if np.linalg.det(world[:3, :3]) < 0:
            n = -n
    if np.linalg.det(world[:3, :3]) < 0:
        tri = tri[:, ::-1]
    return p, n, tri


def _bake_deltas(dp, dn, world):
    """Morph deltas (M, V, 3) moved with a node matrix like :func:`_bake` moves
    the vertices: positions by its linear part, normals by its cofactor divided
    by ``|det|^(2/3)`` (exact for rotation times uniform scale, whose baked unit
    normals the deltas then stay consistent with), flipped when mirrored."""
    A = np.asarray(world, np.float64)[:3, :3]
    det = float(np.linalg.det(A))
    C = math3d.cofactor3(A) / max(abs(det), 1e-300) ** (2.0 / 3.0)
    if det < 0:
        C = -C
    return dp @ A.T, dn @ C.T


def _finish_normals(p, n, tri):
    if n is None:
        return vertex_normals(p, tri).astype(np.float64)
    n = math3d.normalize_vectors(n, fallback=(0.0, 0.0, 0.0))
    bad = ~np.any(n != 0.0, axis=1)
    if np.any(bad):
        n[bad] = vertex_normals(p, tri)[bad]
    return n
