"""Vertex formats of the triangle representations (skinned, static): the attributes a program reads, packed.

Unpacked (the default, see :data:`PACKED_VERTICES`), a skinned vertex is 60 bytes (position, normal 3 x f32; colour, weights 4 x f32; joints 4 x u8).
Packed: position 3 x f32 (exact: crowds of characters far from their model origin need it),
normal 3 x f16, colour 4 x f16, weights 4 x f16, joints 4 x u8 (u16 above 256 joints) = 38 bytes; a static
vertex 40 -> 26 bytes. The shaders read the same ``vec3``/``vec4`` inputs either way (GL converts). Half
floats convert to float exactly on every GL, so tables that must hold the very values the vertex shader
reads (the geomorph targets, render/clusters/morph.py) use :func:`drawn` for them.

What packing changes in the image: normals, colours and weights deviate by < 2^-11 relative (weights
summing to 1 +- 1e-3 move a vertex by at most 1e-3 of its distance from the joints' origins, below a pixel at
crowd scale; a colour by less than a quarter of an 8-bit level). tests/render/test_vertex_format.py bounds
the image difference (PSNR) on a crowd.

On llvmpipe vertex fetch is part of the vertex shader's per-vertex cost (scripts/bench_full_detail.md has its
measured share).
"""
from __future__ import annotations

import numpy as np

#: pack vertex attributes (module default; ``Renderer.packed_vertices`` overrides it per renderer). Off: on
#: llvmpipe the packed format measured no faster (0.96x CPU time on 100 x 60 K-triangle characters,
#: scripts/bench_full_detail.md: the half-float conversion costs what the smaller fetch saves), and unpacked
#: keeps the images bit for bit; a GPU with less memory bandwidth may prefer it on.
PACKED_VERTICES = False


def joint_attribute(joints: np.ndarray, make_buffer) -> tuple:
    """(buffer, format, name) of the joint-index attribute in the narrowest
    unsigned type that holds every index (uint8 for up to 256 joints)."""
    j = np.asarray(joints)
    top = int(j.max()) if j.size else 0
    dtype, fmt = (np.uint8, "4u1") if top < 256 else (np.uint16, "4u2")
    return make_buffer(j.astype(dtype), "joints"), fmt, "in_joints"


def _half(a, n: int) -> np.ndarray:
    """(V, n) float16 of finite float data (values beyond the float16 range are clamped to it)."""
    a = np.asarray(a, np.float32).reshape(-1, n)
    return np.clip(a, -65504.0, 65504.0).astype(np.float16)


def drawn(values, n: int, packed: bool = PACKED_VERTICES) -> np.ndarray:
    """(V, n) float32: ``values`` (normals, colours or weights) as the vertex shader reads them."""
    return _half(values, n).astype(np.float32) if packed else np.asarray(values, np.float32).reshape(-1, n)


def surface_attributes(rep, make_buffer, packed: bool = PACKED_VERTICES) -> list:
    """[(buffer, format, attribute name)] of position, normal and colour of a skinned or static rep."""
    if not packed:
        return [(make_buffer(rep.positions, "positions"), "3f", "in_position"),
                (make_buffer(rep.normals, "normals"), "3f", "in_normal"),
                (make_buffer(rep.colors, "colors"), "4f", "in_color")]
    return [(make_buffer(np.asarray(rep.positions, np.float32), "positions"), "3f", "in_position"),
            (make_buffer(_half(rep.normals, 3), "normals"), "3f2", "in_normal"),
            (make_buffer(_half(rep.colors, 4), "colors"), "4f2", "in_color")]


def compact_influences(joints, weights) -> tuple:
    """(joints (V, 4), weights (V, 4) float32, n): every vertex's non-zero weights moved to the front in their
    order (zeros after them), and n = the most non-zero weights of any vertex (1 ..= 4).

    The skinning loop (``shaders/poses/skinning.glsl``) skips zero weights, so a program compiled to read only the
    first n influences (``SKIN_INFLUENCES_n``) adds the very same terms in the very same order (the shader
    compiler may contract them into fused multiply-adds differently: tests/render/test_skin_influences.py
    bounds the image difference).
    """
    j = np.asarray(joints).reshape(-1, 4)
    w = np.asarray(weights, np.float32).reshape(-1, 4)
    order = np.argsort(w == 0.0, axis=1, kind="stable")
    rows = np.arange(w.shape[0])[:, None]
    n = int(np.count_nonzero(w != 0.0, axis=1).max()) if w.shape[0] else 1
    return j[rows, order], w[rows, order], max(1, n)


def skin_attributes(rep, make_buffer, packed: bool = PACKED_VERTICES, joints=None, weights=None) -> list:
    """[(buffer, format, attribute name)] of joints and weights of a skinned rep (or of ``joints`` and
    ``weights`` given in their place, e.g. by :func:`compact_influences`)."""
    joints = rep.joints if joints is None else joints
    weights = rep.weights if weights is None else weights
    w = (make_buffer(_half(weights, 4), "weights"), "4f2", "in_weights") if packed else \
        (make_buffer(np.asarray(weights, np.float32), "weights"), "4f", "in_weights")
    return [joint_attribute(joints, make_buffer), w]

