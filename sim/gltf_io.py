"""glTF 2.0 import and export of animated characters.

Import (:func:`load_gltf`) turns the default scene of a ``.glb`` or ``.gltf``
file into one :class:`sim.character.SkinnedCharacter` (skins, node TRS
animation, rigid parts) or :class:`sim.character.KeyframedCharacter` (morph
target animation, one keyframe per key time). Export (:func:`save_glb`) writes
either kind back as a binary glTF.

Notes
-----
Follows the Khronos glTF 2.0 specification (version 2.0.1): §3.6 binary data
storage (buffers, buffer views with ``byteStride``; §3.6.2 accessors,
normalized integers and sparse storage), §3.7.2 meshes and morph targets,
§3.7.3 skins (joint matrix = global joint transform x inverse bind matrix;
the skinned mesh node's own transform is ignored), §3.11 animations with
Appendix C (LINEAR, STEP, CUBICSPLINE interpolation) and chapter 4 (the GLB
container).

Where it departs from a full viewer:

- All meshes of the scene are merged into one :class:`sim.mesh.Mesh`. Several
  skins become one skeleton over the union of their joints. Nodes that are not
  joints but lie between joints, carry a rigid (non-skinned) mesh, or are
  animated ancestors of joints are added as extra joints; a rigid mesh is
  bound with weight 1 to its node's joint, so node animation still plays.
- Textures are not kept; when a primitive has a base colour texture and
  ``TEXCOORD_0``, the texture is sampled (nearest texel, Pillow) at every
  vertex and multiplied into the vertex colour, so the model stays readable.
- Morph targets on a skinned mesh are applied at their default weights; their
  weight animations are ignored (with a warning).
- More than four influences (``JOINTS_1``/``WEIGHTS_1``) keep the four
  largest, renormalised. When the skeleton's roots hang below different
  parent nodes, every ancestor becomes a joint (``root_transform`` = identity).
- The container and JSON are parsed here rather than by pygltflib so that
  every defect gets a precise message; pygltflib writes the exported file.

Every problem with the input raises :class:`sim.errors.AssetError` with one
sentence naming the file and the offending element.
"""
from __future__ import annotations

import base64
import io
import json
import os
import struct
import tempfile
import urllib.parse
import warnings
from pathlib import Path

import numpy as np

from sim import math3d
from sim.character import KeyframedCharacter, SkinnedCharacter
from sim.clip import Channel, Clip
from sim.errors import AssetError
from sim.mesh import Mesh, vertex_normals
from sim.skeleton import Skeleton

#: Extensions whose presence in ``extensionsRequired`` we accept: quantized
#: attributes are read as normal accessors; material and texture extensions
#: only change shading, which we do not reproduce.
GLTF_ACCEPTED_REQUIRED_EXTENSIONS = frozenset(
    {
        "KHR_mesh_quantization",
        "KHR_texture_transform",
        "KHR_materials_unlit",
        "KHR_materials_emissive_strength",
        "KHR_materials_ior",
        "KHR_materials_specular",
        "KHR_materials_transmission",
        "KHR_materials_volume",
        "KHR_materials_clearcoat",
        "KHR_materials_sheen",
        "KHR_materials_iridescence",
        "KHR_materials_anisotropy",
        "KHR_materials_pbrSpecularGlossiness",
        "KHR_texture_basisu",
        "EXT_texture_webp",
    }
)
#: Compression extensions we refuse with a specific message.
GLTF_COMPRESSION_EXTENSIONS = frozenset(
    {"KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression"}
)
#: Vertex colour used where a primitive has neither COLOR_0 nor a material
#: (the glTF default material's baseColorFactor).
GLTF_DEFAULT_COLOR = (1.0, 1.0, 1.0, 1.0)
#: Largest accepted accessor element count (guards against absurd allocations).
GLTF_MAX_COUNT = 1 << 28
#: Two morph weight vectors closer than this are "the same key" (closed loops).
GLTF_LOOP_TOL = 1e-6

_GLB_MAGIC = 0x46546C67  # b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942

_COMPONENT = {
    5120: np.dtype("<i1"),
    5121: np.dtype("<u1"),
    5122: np.dtype("<i2"),
    5123: np.dtype("<u2"),
    5125: np.dtype("<u4"),
    5126: np.dtype("<f4"),
}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 4: "TRIANGLES", 5: "TRIANGLE_STRIP", 6: "TRIANGLE_FAN"}


# --------------------------------------------------------------------------- container


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)



class _Doc:
    """A parsed glTF document: JSON, buffers, and cached accessor reads."""

    def __init__(self, path: Path):
        self.path = path
        self.name = path.name
        data = self._read_bytes()
        bin_chunk = None
        if data[:4] == b"glTF" or (path.suffix.lower() == ".glb" and data.lstrip()[:1] != b"{"):
            text, bin_chunk = self._parse_glb(data)
        else:
            text = data
        try:
            # some exporters pad the GLB JSON chunk with NULs instead of spaces
            self.json = json.loads(text.rstrip(b"\x00 \t\r\n").decode("utf-8-sig"))
        except UnicodeDecodeError:
            self.fail("JSON is not UTF-8 text")
        except json.JSONDecodeError as e:
            self.fail(f"invalid JSON at line {e.lineno} column {e.colno}: {e.msg}")
        if not isinstance(self.json, dict):
            self.fail("the JSON document is not an object")
        asset = self.json.get("asset")
        version = str(asset.get("version", "")) if isinstance(asset, dict) else ""
        if not version.startswith("2."):
            self.fail(f"asset.version is {version or 'missing'!r}; only glTF 2.x is accepted")
        self._check_extensions()
        self.bin_chunk = bin_chunk
        self.ctx = "document"  # element being read, named by the fallback error
        self._buffers: dict[int, bytes] = {}
        self._accessors: dict[int, np.ndarray] = {}

    # -- errors
    def fail(self, msg: str):
        raise AssetError(f"{self.name}: {msg}")

    # -- reading
    def _read_bytes(self) -> bytes:
        try:
            return self.path.read_bytes()
        except FileNotFoundError:
            raise AssetError(f"{self.path}: file not found") from None
        except OSError as e:
            raise AssetError(f"{self.path}: cannot read file ({e.strerror})") from None

    def _parse_glb(self, data: bytes) -> tuple[bytes, bytes | None]:
        """GLB container (spec §4.4): 12-byte header, JSON chunk, optional BIN chunk."""
        if len(data) < 12:
            self.fail(f"truncated GLB: {len(data)} bytes, the header alone needs 12")
        magic, version, length = struct.unpack_from("<III", data, 0)
        if magic != _GLB_MAGIC:
            self.fail(f"bad GLB magic {data[:4]!r}, expected b'glTF'")
        if version != 2:
            self.fail(f"GLB container version {version}; only version 2 is accepted")
        if length > len(data):
            self.fail(f"truncated GLB: header says {length} bytes, file has {len(data)}")
        off = 12
        chunks = []
        while off < length:
            if off + 8 > length:
                self.fail(f"truncated GLB: chunk header at byte {off} runs past the end ({length} bytes)")
            clen, ctype = struct.unpack_from("<II", data, off)
            if off + 8 + clen > length:
                self.fail(f"truncated GLB: chunk {len(chunks)} needs {clen} bytes at byte {off + 8}, file has {length}")
            chunks.append((ctype, data[off + 8 : off + 8 + clen]))
            off += 8 + clen
        if not chunks or chunks[0][0] != _CHUNK_JSON:
            self.fail("GLB has no JSON chunk first")
        bin_chunk = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _CHUNK_BIN else None
        return chunks[0][1], bin_chunk

    def _check_extensions(self):
        req = self.json.get("extensionsRequired") or []
        for ext in req:
            if ext in GLTF_COMPRESSION_EXTENSIONS:
                self.fail(
                    f"extensionsRequired: {ext} compressed geometry is not supported; "
                    "re-export the file without mesh compression (e.g. gltf-transform copy)"
                )
            if ext not in GLTF_ACCEPTED_REQUIRED_EXTENSIONS:
                self.fail(
                    f"extensionsRequired: unknown extension {ext!r}; accepted are "
                    + ", ".join(sorted(GLTF_ACCEPTED_REQUIRED_EXTENSIONS))
                )

    # -- JSON access
    def items(self, key: str) -> list:
        v = self.json.get(key, [])
        if not isinstance(v, list):
            self.fail(f"{key} is not an array")
        return v

    def item(self, key: str, i, where: str = "") -> dict:
        arr = self.items(key)
        if not _is_int(i) or not 0 <= i < len(arr):
            self.fail(f"{where + ': ' if where else ''}{key}[{i}] does not exist ({len(arr)} {key})")
        v = arr[i]
        if not isinstance(v, dict):
            self.fail(f"{key}[{i}] is not an object")
        return v

    # -- buffers
    def buffer(self, i: int) -> bytes:
        if i in self._buffers:
            return self._buffers[i]
        b = self.item("buffers", i)
        where = f"buffers[{i}]"
        uri = b.get("uri")
        if uri is None:
            if i != 0 or self.bin_chunk is None:
                self.fail(f"{where} has no uri and there is no GLB binary chunk")
            data = self.bin_chunk
        elif uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                self.fail(f"{where}: data URI is not base64")
            try:
                data = base64.b64decode(payload, validate=False)
            except (ValueError, TypeError):
                self.fail(f"{where}: data URI is not valid base64")
        else:
            rel = urllib.parse.unquote(uri)
            p = (self.path.parent / rel).resolve()
            try:
                data = p.read_bytes()
            except OSError:
                self.fail(f"{where}: external buffer {rel!r} not found next to the file")
        n = b.get("byteLength")
        if not isinstance(n, int) or n < 0:
            self.fail(f"{where}: byteLength missing or invalid")
        if len(data) < n:
            self.fail(f"{where}: has {len(data)} bytes, byteLength says {n}")
        self._buffers[i] = data
        return data

    def buffer_view(self, i: int, where: str) -> tuple[bytes, int, int, int | None]:
        """(buffer bytes, start, length, byteStride) of bufferViews[i], bounds-checked."""
        bv = self.item("bufferViews", i, where)
        data = self.buffer(bv.get("buffer", -1) if isinstance(bv.get("buffer"), int) else -1)
        start = bv.get("byteOffset", 0)
        length = bv.get("byteLength", -1)
        if not _is_int(length) or length < 0 or not _is_int(start) or start < 0:
            self.fail(f"bufferViews[{i}]: byteOffset/byteLength missing or negative")
        stride = bv.get("byteStride")
        if stride is not None and (not _is_int(stride) or not 4 <= stride <= 252 or stride % 4):
            self.fail(f"bufferViews[{i}]: byteStride {stride!r} is not a multiple of 4 in 4..252")
        if start + length > len(data):
            self.fail(f"bufferViews[{i}]: bytes {start}..{start + length} lie outside its buffer of {len(data)} bytes")
        return data, start, length, stride

    # -- accessors
    def accessor(self, i: int, where: str = "") -> np.ndarray:
        """Accessor ``i`` as (count, ncomp) array: float64 for float or normalized
        accessors, the integer dtype otherwise (spec §3.6.2, §3.11 normalized ints)."""
        a = self.item("accessors", i, where)
        if i in self._accessors:
            return self._accessors[i]
        w = f"accessors[{i}]"
        self.ctx = w
        ct, typ, count = a.get("componentType"), a.get("type"), a.get("count")
        if not _is_int(ct) or ct not in _COMPONENT:
            self.fail(f"{w}: componentType {ct!r} is not one of {sorted(_COMPONENT)}")
        if not isinstance(typ, str) or typ not in _NCOMP:
            self.fail(f"{w}: type {typ!r} is not one of {', '.join(_NCOMP)}")
        if not _is_int(count) or not 0 <= count <= GLTF_MAX_COUNT:
            self.fail(f"{w}: count {count!r} is not an integer in 0..{GLTF_MAX_COUNT}")
        dt, nc = _COMPONENT[ct], _NCOMP[typ]
        esize = dt.itemsize * nc
        if "bufferView" in a:
            data, start, length, stride = self.buffer_view(a["bufferView"], w)
            off = a.get("byteOffset", 0)
            if not _is_int(off) or off < 0:
                self.fail(f"{w}: byteOffset invalid")
            stride = stride or esize
            if stride < esize:
                self.fail(f"{w}: byteStride {stride} is smaller than the element size {esize}")
            need = off + (stride * (count - 1) + esize if count else 0)
            if need > length:
                self.fail(f"{w}: {count} elements of {esize} bytes (stride {stride}) need {need} bytes, bufferView has {length}")
            if count:
                arr = np.ndarray((count, nc), dt, buffer=data, offset=start + off, strides=(stride, dt.itemsize)).copy()
            else:
                arr = np.zeros((0, nc), dt)
        else:
            arr = np.zeros((count, nc), dt)
        sp = a.get("sparse")
        if sp:
            arr = self._apply_sparse(arr, sp, w, dt, nc)
        if a.get("normalized"):
            if dt.kind == "f" or dt.itemsize == 4:
                self.fail(f"{w}: normalized is only valid for 8/16-bit integer components")
            info = np.iinfo(dt)
            arr = np.maximum(arr.astype(np.float64) / info.max, -1.0)
        elif dt.kind == "f":
            arr = arr.astype(np.float64)
        self._accessors[i] = arr
        return arr

    def _apply_sparse(self, arr, sp, w, dt, nc):
        n = sp.get("count", 0) if isinstance(sp, dict) else -1
        if not _is_int(n) or not 0 <= n <= arr.shape[0]:
            self.fail(f"{w}.sparse: count {n!r} is not an integer in 0..{arr.shape[0]}")
        idx_d, val_d = sp.get("indices") or {}, sp.get("values") or {}
        o1, o2 = idx_d.get("byteOffset", 0), val_d.get("byteOffset", 0)
        if not (_is_int(o1) and _is_int(o2) and o1 >= 0 and o2 >= 0):
            self.fail(f"{w}.sparse: byteOffset must be a non-negative integer")
        ict = idx_d.get("componentType")
        if ict not in (5121, 5123, 5125):
            self.fail(f"{w}.sparse.indices: componentType {ict!r} is not an unsigned integer type")
        idt = _COMPONENT[ict]
        d, s, ln, _ = self.buffer_view(idx_d.get("bufferView", -1), f"{w}.sparse.indices")
        o = idx_d.get("byteOffset", 0)
        if o + n * idt.itemsize > ln:
            self.fail(f"{w}.sparse.indices: {n} indices overrun their bufferView")
        idx = np.frombuffer(d, idt, n, s + o).astype(np.int64)
        d, s, ln, _ = self.buffer_view(val_d.get("bufferView", -1), f"{w}.sparse.values")
        o = val_d.get("byteOffset", 0)
        if o + n * nc * dt.itemsize > ln:
            self.fail(f"{w}.sparse.values: {n} values overrun their bufferView")
        vals = np.frombuffer(d, dt, n * nc, s + o).reshape(n, nc)
        if n and (idx.min() < 0 or idx.max() >= arr.shape[0]):
            self.fail(f"{w}.sparse.indices: index {int(idx.max())} out of range for {arr.shape[0]} elements")
        arr = arr.copy()
        arr[idx] = vals
        return arr

    def floats(self, i: int, where: str, ncomp: tuple[int, ...], finite: bool = True) -> np.ndarray:
        a = self.accessor(i, where)
        if a.shape[1] not in ncomp:
            self.fail(f"{where}: accessors[{i}] has {a.shape[1]} components, expected {' or '.join(map(str, ncomp))}")
        a = a.astype(np.float64)
        if finite and not np.all(np.isfinite(a)):
            self.fail(f"{where}: accessors[{i}] contains NaN or infinite values")
        return a


# --------------------------------------------------------------------------- scene graph


def _node_local(doc: _Doc, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(matrix (4,4), translation (3,), rotation (4,), scale (3,)) of nodes[i]."""
    n = doc.item("nodes", i)
    doc.ctx = f"nodes[{i}]"
    try:
        if "matrix" in n:
            m = np.asarray(n["matrix"], np.float64).reshape(4, 4).T  # column-major in JSON
            t = m[:3, 3].copy()
            lin = m[:3, :3]
            s = np.linalg.norm(lin, axis=0)
            if np.linalg.det(lin) < 0:
                s[0] = -s[0]
            r = math3d.matrix_to_quat(lin / np.where(np.abs(s) > 1e-30, s, 1.0))
        else:
            t = np.asarray(n.get("translation", (0, 0, 0)), np.float64).reshape(3)
            r = np.asarray(n.get("rotation", (0, 0, 0, 1)), np.float64).reshape(4)
            s = np.asarray(n.get("scale", (1, 1, 1)), np.float64).reshape(3)
            r = math3d.quat_normalize(r)
            m = math3d.trs_matrix(t, r, s)
    except (ValueError, TypeError):
        doc.fail(f"nodes[{i}]: matrix/translation/rotation/scale have the wrong length or type")
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(r))):
        doc.fail(f"nodes[{i}]: transform contains NaN or infinite values")
    return m, t, r, s


class _Graph:
    """Parent links, world matrices and the default scene's node set."""

    def __init__(self, doc: _Doc):
        nodes = doc.items("nodes")
        self.n = len(nodes)
        self.parent = np.full(self.n, -1, np.int64)
        self.children: list[list[int]] = [[] for _ in range(self.n)]
        for i in range(self.n):
            nd = doc.item("nodes", i)
            for c in nd.get("children", []):
                if not _is_int(c) or not 0 <= c < self.n:
                    doc.fail(f"nodes[{i}].children: node {c!r} does not exist ({self.n} nodes)")
                if c == i:
                    doc.fail(f"nodes[{i}]: cyclic node hierarchy (node is its own child)")
                if self.parent[c] >= 0:
                    doc.fail(f"nodes[{c}] has two parents (nodes[{self.parent[c]}] and nodes[{i}]); the node hierarchy must be a forest")
                self.parent[c] = i
                self.children[i].append(c)
        # cycle detection: walking up from any node must end at a root
        state = np.zeros(self.n, np.int8)  # 0 unknown, 1 reaches a root
        for i in range(self.n):
            path, j = [], i
            while j >= 0 and state[j] == 0:
                if j in path:
                    doc.fail(f"nodes[{j}]: cyclic node hierarchy")
                path.append(j)
                if len(path) > self.n:
                    doc.fail(f"nodes[{j}]: cyclic node hierarchy")
                j = int(self.parent[j])
            state[path] = 1
        self.local = []
        self.trs = []
        for i in range(self.n):
            m, t, r, s = _node_local(doc, i)
            self.local.append(m)
            self.trs.append((t, r, s))
        self.world = [None] * self.n
        for i in self.topo_order():
            p = self.parent[i]
            self.world[i] = self.local[i] if p < 0 else self.world[p] @ self.local[i]
        # default scene
        scenes = doc.items("scenes")
        if scenes:
            si = doc.json.get("scene", 0)
            sc = doc.item("scenes", si, "scene")
            roots = sc.get("nodes", [])
            for r in roots:
                if not _is_int(r) or not 0 <= r < self.n:
                    doc.fail(f"scenes[{si}].nodes: node {r!r} does not exist ({self.n} nodes)")
        else:
            roots = [i for i in range(self.n) if self.parent[i] < 0]
        self.scene_nodes: list[int] = []
        stack = list(reversed(roots))
        while stack:
            i = stack.pop()
            self.scene_nodes.append(i)
            stack.extend(reversed(self.children[i]))

    def topo_order(self) -> list[int]:
        depth = np.zeros(self.n, np.int64)
        for i in range(self.n):
            d, j = 0, self.parent[i]
            while j >= 0:
                d += 1
                j = self.parent[j]
            depth[i] = d
        return [int(i) for i in np.argsort(depth, kind="stable")]

    def ancestors(self, i: int) -> list[int]:
        out, j = [], int(self.parent[i])
        while j >= 0:
            out.append(j)
            j = int(self.parent[j])
        return out


# --------------------------------------------------------------------------- primitives


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


def _finish_normals(p, n, tri):
    if n is None:
        return vertex_normals(p, tri).astype(np.float64)
    n = math3d.normalize_vectors(n, fallback=(0.0, 0.0, 0.0))
    bad = ~np.any(n != 0.0, axis=1)
    if np.any(bad):
        n[bad] = vertex_normals(p, tri)[bad]
    return n


# --------------------------------------------------------------------------- animations


def _read_sampler(doc: _Doc, ai: int, anim: dict, si, ncomp: tuple[int, ...] | None):
    """(times (K,), values (K, C) or (K, 3, C), interpolation) of a sampler."""
    where = f"animations[{ai}].samplers[{si}]"
    samplers = anim.get("samplers") or []
    if not _is_int(si) or not 0 <= si < len(samplers):
        doc.fail(f"animations[{ai}]: sampler {si!r} does not exist ({len(samplers)} samplers)")
    s = samplers[si]
    interp = s.get("interpolation", "LINEAR")
    if interp not in ("LINEAR", "STEP", "CUBICSPLINE"):
        doc.fail(f"{where}: interpolation {interp!r}; accepted are LINEAR, STEP, CUBICSPLINE")
    t = doc.floats(s.get("input", -1), f"{where}.input", (1,))[:, 0]
    v = doc.floats(s.get("output", -1), f"{where}.output", ncomp or (1, 2, 3, 4))
    K = t.shape[0]
    if K == 0:
        doc.fail(f"{where}: no keys")
    if np.any(np.diff(t) < 0):
        doc.fail(f"{where}: key times are not increasing")
    if np.any(t < 0):
        doc.fail(f"{where}: negative key time {float(t.min())}")
    per = 3 if interp == "CUBICSPLINE" else 1
    if v.shape[0] % (K * per):
        doc.fail(f"{where}: {v.shape[0]} output values do not match {K} keys ({interp})")
    width = v.shape[0] // (K * per)  # >1 for morph weights
    v = v.reshape(K, per, width * v.shape[1]) if per == 3 else v.reshape(K, width * v.shape[1])
    # duplicate key times: keep the last key of each run (Channel needs strictly increasing)
    keep = np.ones(K, bool)
    keep[:-1] = np.diff(t) > 0
    if not keep.all():
        t, v = t[keep], v[keep]
    return t, v, interp


def _sample_channel(t, v, interp, times):
    """Sample (non-rotation) values at times (N,) -> (N, C) via sim.clip.Channel."""
    ch = Channel(joint=0, path="weights", times=t, values=v, interpolation=interp)
    return ch.sample(np.asarray(times, np.float64))


def _unique_name(base: str, used: set) -> str:
    name, k = base, 1
    while name in used:
        name = f"{base}.{k}"
        k += 1
    used.add(name)
    return name


# --------------------------------------------------------------------------- loader


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
    if morph_animated:
        warnings.warn(f"{doc.name}: morph weight animations on a skinned/node-animated model are ignored", stacklevel=3)
    return _load_skinned(doc, g, mesh_nodes, skinned_nodes, prims, trs_targets & in_scene)


def _load_skinned(doc, g: _Graph, mesh_nodes, skinned_nodes, prims, animated):
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
    # ---- merged mesh
    P, N, C, T, JO, W = [], [], [], [], [], []
    nv = 0
    zero_total = 0
    for ni in mesh_nodes:
        nd = doc.item("nodes", ni)
        for pr in prims[ni]:
            p, n, c = pr.morphed(None)
            tri = pr.tri
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
                jj = np.zeros((p.shape[0], 4), np.int64)
                jj[:, 0] = jk
                ww = np.zeros((p.shape[0], 4))
                ww[:, 0] = 1.0
                fallback = jk
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
            T.append(tri + nv)
            JO.append(jj)
            W.append(ww)
            nv += p.shape[0]
    if zero_total:
        warnings.warn(f"{doc.name}: {zero_total} vertices have all-zero skin weights; bound to their mesh node's joint (or joint 0)", stacklevel=3)
    mesh = Mesh(
        positions=np.concatenate(P).astype(np.float32),
        indices=np.concatenate(T).astype(np.uint32).reshape(-1, 3),
        normals=np.concatenate(N).astype(np.float32),
        colors=np.concatenate(C).astype(np.float32),
        joints=np.concatenate(JO).astype(np.uint16),
        weights=np.concatenate(W).astype(np.float32),
    )
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
            if path_ not in ("translation", "rotation", "scale") or node not in jindex:
                continue  # weights, or a node that affects nothing we draw
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
    return SkinnedCharacter(name=doc.path.stem, mesh=mesh, skeleton=skeleton, clips=clips, source=str(doc.path))


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
    if not animations:
        name = "rest"
        animations[name] = keyframes.from_meshes(name, np.array([0.0]), [build(None)], correspondences=None, loop=True, duration=1.0)
    return KeyframedCharacter(name=doc.path.stem, animations=animations, source=str(doc.path))


# --------------------------------------------------------------------------- export


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
        WEIGHTS_0 (float), a skin with inverse bind matrices, one node per
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
    gl["asset"] = {"version": "2.0", "generator": "crowd-sandbox sim.gltf_io"}
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
    prim = _mesh_primitive(w, m.positions, m.ensure_normals(), m.vertex_colors(), m.indices, extra)
    ib = w.add(_f32(np.asarray(sk.inverse_bind, np.float64).transpose(0, 2, 1)).reshape(J, 16), "MAT4")
    nodes.append({"name": str(ch.name), "mesh": 0, "skin": 0})
    scene_nodes.append(len(nodes) - 1)
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
        if channels:
            anims.append({"name": str(name), "samplers": samplers, "channels": channels,
                          "extras": {"loop": bool(clip.loop), "duration": float(clip.duration)}})
    gl = {
        "scenes": [{"nodes": scene_nodes}],
        "nodes": nodes,
        "meshes": [{"name": str(ch.name), "primitives": [prim]}],
        "skins": [skin],
    }
    if anims:
        gl["animations"] = anims
    return gl


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
