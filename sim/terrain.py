"""Heightfield terrain: procedural fBm value noise or a height image / array.

The landscape of Wand & Straßer 2002, §5.2 (horses running through a
landscape). A regular grid of ``resolution[0] x resolution[1]`` height samples
spans ``size`` metres from ``origin`` (the sample (0, 0) is at
``(origin.x, origin.y + h, origin.z)``). Heights between samples are bilinear;
outside the grid the coordinates are clamped to its border.

Sources (``[terrain]`` table, see :data:`PARAMS`):

- procedural (``file = ""``): fractional Brownian motion of value noise,
  ``sum_o persistence^o * noise(frequency * lacunarity^o * uv)`` over
  ``octaves``, each octave a lattice of uniform random values from
  ``numpy.random.default_rng(seed)`` interpolated with smoothstep, then
  normalised to [0, 1]; deterministic for a seed.
- ``*.png``: 8-bit or 16-bit greyscale (Pillow), normalised to [0, 1]; row 0 of
  the image is the -z edge (z grows with the row).
- ``*.npz``: an array named ``height`` of shape (rows along z, columns along x).

Every source is multiplied by ``height_scale`` (metres per unit) and offset by
``origin.y``.
"""
from __future__ import annotations

import math
import os

import numpy as np

from sim.config import TERRAIN_MAX_RESOLUTION
from sim.errors import AssetError
from sim.params import Param

PARAMS: dict[str, Param] = {
    "file": Param("str", "", doc="height image (.png, 8/16-bit grey) or .npz with `height`; "
                                 "relative to the scene file; empty = procedural noise"),
    "size": Param("vec2", [400.0, 400.0], doc="extent along x, z, metres (> 0)"),
    "origin": Param("vec3", [-200.0, 0.0, -200.0], doc="position of the (xmin, zmin) corner at height 0, metres"),
    "resolution": Param("int", 257, min=2, max=TERRAIN_MAX_RESOLUTION,
                        doc="samples per side of procedural terrain (files keep their own)"),
    "height_scale": Param("float", 15.0, min=0.0, max=1e5, doc="metres per unit of height"),
    "seed": Param("int", 0, min=0, doc="procedural noise seed"),
    "octaves": Param("int", 5, min=1, max=16, doc="noise octaves"),
    "frequency": Param("float", 3.0, min=1e-3, max=1e4, doc="lattice cells across the terrain, first octave"),
    "persistence": Param("float", 0.5, min=0.0, max=1.0, doc="amplitude factor per octave"),
    "lacunarity": Param("float", 2.0, min=1.0, max=8.0, doc="frequency factor per octave"),
}


def fbm_value_noise(nx: int, nz: int, seed: int, octaves: int = 5, frequency: float = 3.0,
                    persistence: float = 0.5, lacunarity: float = 2.0) -> np.ndarray:
    """(nz, nx) float64 fBm value noise in [0, 1] (constant 0.5 if flat)."""
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 1.0, nx)
    v = np.linspace(0.0, 1.0, nz)
    out = np.zeros((nz, nx))
    amp = 1.0
    for o in range(octaves):
        f = frequency * lacunarity ** o
        m = int(math.ceil(f)) + 2
        lat = rng.random((m, m))
        x, z = u * f, v * f
        ix, iz = np.floor(x).astype(np.int64), np.floor(z).astype(np.int64)
        tx, tz = x - ix, z - iz
        sx, sz = tx * tx * (3 - 2 * tx), tz * tz * (3 - 2 * tz)
        a = lat[iz[:, None], ix[None, :]]
        b = lat[iz[:, None], ix[None, :] + 1]
        c = lat[iz[:, None] + 1, ix[None, :]]
        d = lat[iz[:, None] + 1, ix[None, :] + 1]
        top = a + (b - a) * sx[None, :]
        bot = c + (d - c) * sx[None, :]
        out += amp * (top + (bot - top) * sz[:, None])
        amp *= persistence
    lo, hi = out.min(), out.max()
    return (out - lo) / (hi - lo) if hi > lo else np.full_like(out, 0.5)


def load_heights(path: str) -> np.ndarray:
    """(rows, cols) float64 heights from a .png (normalised to [0, 1]) or .npz.

    Raises AssetError naming the file for anything unreadable or unsupported.
    """
    ext = os.path.splitext(path)[1].lower()
    if not os.path.isfile(path):
        raise AssetError(f"{path}: terrain file not found")
    if ext == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                if "height" not in z:
                    raise AssetError(f"{path}: expected an array named 'height', found {sorted(z.files)}")
                h = np.asarray(z["height"], np.float64)
        except AssetError:
            raise
        except Exception as e:  # zipfile / format errors
            raise AssetError(f"{path}: not a readable .npz file ({e})") from None
    elif ext == ".png":
        try:
            from PIL import Image

            with Image.open(path) as im:
                im.load()
                mode = im.mode
                if mode in ("I;16", "I;16B", "I;16L", "I"):
                    h = np.asarray(im, np.float64) / 65535.0
                elif mode in ("L", "P", "RGB", "RGBA", "LA"):
                    h = np.asarray(im.convert("L"), np.float64) / 255.0
                else:
                    raise AssetError(f"{path}: unsupported PNG mode {mode!r}; expected 8- or 16-bit greyscale")
        except AssetError:
            raise
        except Exception as e:
            raise AssetError(f"{path}: not a readable PNG image ({e})") from None
    else:
        raise AssetError(f"{path}: unsupported terrain file type {ext!r}; expected .png or .npz")
    if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 2:
        raise AssetError(f"{path}: expected a 2-D height array of at least 2 x 2 samples, got shape {h.shape}")
    if max(h.shape) > TERRAIN_MAX_RESOLUTION:
        raise AssetError(f"{path}: at most {TERRAIN_MAX_RESOLUTION} samples per side, got shape {h.shape}")
    if not np.isfinite(h).all():
        raise AssetError(f"{path}: height array holds NaN or Inf")
    return h


class Terrain:
    """A heightfield.

    Parameters
    ----------
    heights : (nz, nx) float64, metres above ``origin[1]`` (row = z index)
    size : (sx, sz) metres, > 0
    origin : (x, y, z) of sample (0, 0) at height 0
    """

    def __init__(self, heights: np.ndarray, size=(400.0, 400.0), origin=(-200.0, 0.0, -200.0)):
        h = np.asarray(heights, np.float64)
        if h.ndim != 2 or min(h.shape) < 2 or not np.isfinite(h).all():
            raise ValueError("heights must be a finite (nz >= 2, nx >= 2) array")
        if not (size[0] > 0 and size[1] > 0):
            raise ValueError(f"terrain size must be > 0, got {size!r}")
        self.heights = h
        self.size = (float(size[0]), float(size[1]))
        self.origin = np.asarray(origin, np.float64).reshape(3)
        self.nz, self.nx = h.shape
        self.dx = self.size[0] / (self.nx - 1)
        self.dz = self.size[1] / (self.nz - 1)

    @classmethod
    def from_config(cls, cfg: dict, base_dir: str | None = None) -> "Terrain":
        """Build from a validated ``[terrain]`` table; ``file`` is relative to ``base_dir``."""
        c = {k: p.default for k, p in PARAMS.items()}
        c.update(cfg)
        size = c["size"]
        if not (size[0] > 0 and size[1] > 0):
            from sim.params import ParamError

            raise ParamError("terrain.size", f"expected two numbers > 0, got {size!r}")
        if c["file"]:
            path = c["file"] if base_dir is None else os.path.join(base_dir, c["file"])
            h = load_heights(path)
        else:
            r = int(c["resolution"])
            h = fbm_value_noise(r, r, int(c["seed"]), int(c["octaves"]), float(c["frequency"]),
                                float(c["persistence"]), float(c["lacunarity"]))
        return cls(h * float(c["height_scale"]), size, c["origin"])

    def _cell(self, x, z):
        u = np.clip((np.asarray(x, np.float64) - self.origin[0]) / self.dx, 0.0, self.nx - 1)
        v = np.clip((np.asarray(z, np.float64) - self.origin[2]) / self.dz, 0.0, self.nz - 1)
        i = np.minimum(np.floor(u).astype(np.int64), self.nx - 2)
        j = np.minimum(np.floor(v).astype(np.int64), self.nz - 2)
        return i, j, u - i, v - j

    def height(self, x, z) -> np.ndarray:
        """Bilinear height (metres, world y) at x, z (arrays broadcast; clamped outside)."""
        i, j, s, t = self._cell(x, z)
        h = self.heights
        a, b, c, d = h[j, i], h[j, i + 1], h[j + 1, i], h[j + 1, i + 1]
        return self.origin[1] + (a * (1 - s) + b * s) * (1 - t) + (c * (1 - s) + d * s) * t

    def normal(self, x, z) -> np.ndarray:
        """(..., 3) float64 unit normals of the bilinear surface at x, z (from the
        patch gradient; outside the grid, the border patch's gradient)."""
        i, j, s, t = self._cell(x, z)
        h = self.heights
        a, b, c, d = h[j, i], h[j, i + 1], h[j + 1, i], h[j + 1, i + 1]
        dhdx = ((b - a) * (1 - t) + (d - c) * t) / self.dx
        dhdz = ((c - a) * (1 - s) + (d - b) * s) / self.dz
        n = np.stack([-dhdx, np.ones_like(dhdx), -dhdz], -1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def mesh(self, max_resolution: int = 513):
        """A sim.mesh.Mesh of the terrain (subsampled to at most ``max_resolution``
        samples per side), coloured by height (green to brown to white) and
        darkened on steep slopes. Positions are float32 world coordinates."""
        from sim.mesh import Mesh

        sx = max(1, int(math.ceil((self.nx - 1) / (max_resolution - 1))))
        sz = max(1, int(math.ceil((self.nz - 1) / (max_resolution - 1))))
        xi = np.unique(np.r_[np.arange(0, self.nx, sx), self.nx - 1])
        zi = np.unique(np.r_[np.arange(0, self.nz, sz), self.nz - 1])
        X = self.origin[0] + xi * self.dx
        Z = self.origin[2] + zi * self.dz
        H = self.origin[1] + self.heights[np.ix_(zi, xi)]
        mx, mz = len(xi), len(zi)
        pos = np.stack([np.broadcast_to(X[None, :], (mz, mx)), H, np.broadcast_to(Z[:, None], (mz, mx))], -1)
        pos = pos.reshape(-1, 3)
        nrm = self.normal(pos[:, 0], pos[:, 2])
        k = np.arange(mx * mz).reshape(mz, mx)
        a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel()
        # counter-clockwise seen from +Y (right-handed, Y up): a, c, b and b, c, d
        idx = np.stack([np.stack([a, c, b], 1), np.stack([b, c, d], 1)], 1).reshape(-1, 3)
        h = pos[:, 1] - self.origin[1]
        rng = float(np.ptp(self.heights)) or 1.0
        u = np.clip((h - self.heights.min()) / rng, 0, 1)[:, None]
        low, mid, top = np.array([0.25, 0.45, 0.18]), np.array([0.45, 0.36, 0.25]), np.array([0.92, 0.92, 0.95])
        col = np.where(u < 0.6, low + (mid - low) * (u / 0.6), mid + (top - mid) * ((u - 0.6) / 0.4))
        col *= (0.55 + 0.45 * nrm[:, 1:2])  # steeper = darker
        rgba = np.concatenate([col, np.ones((col.shape[0], 1))], 1).astype(np.float32)
        return Mesh(positions=pos.astype(np.float32), indices=idx.astype(np.uint32),
                    normals=nrm.astype(np.float32), colors=rgba)
