"""The glTF container: the file's JSON document, its buffers and its accessors.

:class:`_Doc` reads a ``.glb`` or ``.gltf`` file and hands out the JSON
elements (bounds-checked) and accessors as numpy arrays; the other reading
modules of :mod:`sim.gltf` work on it.

Notes
-----
Follows the Khronos glTF 2.0 specification (version 2.0.1): §3.6 binary data
storage (buffers, buffer views with ``byteStride``; §3.6.2 accessors,
normalized integers and sparse storage) and chapter 4 (the GLB container).
Buffers come from the GLB binary chunk, base64 data URIs, or files relative
to the ``.gltf``.

The container and JSON are parsed here rather than by pygltflib so that every
defect gets a precise message (pygltflib writes the exported file,
:mod:`sim.gltf.write`): :meth:`_Doc.fail` raises
:class:`sim.errors.AssetError` with one sentence naming the file and the
offending element. Required extensions are accepted only from
:data:`GLTF_ACCEPTED_REQUIRED_EXTENSIONS`; mesh compression is refused.
"""
from __future__ import annotations

import base64
import json
import struct
import urllib.parse
from pathlib import Path

import numpy as np

from sim.errors import AssetError

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
#: Largest accepted accessor element count (guards against absurd allocations).
GLTF_MAX_COUNT = 1 << 28

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
