"""Image error of a rendered frame against its full-detail reference.

PSNR, SSIM (Wang, Bovik, Sheikh, Simoncelli, "Image Quality Assessment: From
Error Visibility to Structural Similarity", IEEE TIP 2004, §III-B/C: Gaussian
window sigma 1.5, K1 = 0.01, K2 = 0.03) and FLIP (Andersson et al., "FLIP: A
Difference Evaluator for Alternating Images", HPG 2020, through the
``flip-evaluator`` package when it is installed).

Images are (h, w, 3) uint8 sRGB (as ``render.renderer.Renderer.read_pixels``
returns) or float in [0, 1]. All functions are vectorised numpy/scipy; there is
no per-pixel Python loop.
"""
from __future__ import annotations

import math

import numpy as np

#: SSIM constants (Wang et al. 2004, §III-C)
SSIM_K1, SSIM_K2, SSIM_SIGMA = 0.01, 0.03, 1.5
#: the Gaussian window is cut at this many sigmas (3.5 * 1.5 -> an 11x11 window, as in the paper)
SSIM_TRUNCATE = 3.5


def as_float(img: np.ndarray) -> np.ndarray:
    """(h, w, c) image -> float64 in [0, 1] (uint8 is divided by 255; floats are clipped)."""
    a = np.asarray(img)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3:
        raise ValueError(f"expected an (h, w, c) image, got shape {a.shape}")
    if a.dtype == np.uint8:
        return a.astype(np.float64) / 255.0
    a = np.asarray(a, np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError("image has NaN or Inf values")
    return np.clip(a, 0.0, 1.0)


def _pair(test, reference):
    t, r = as_float(test), as_float(reference)
    if t.shape != r.shape:
        raise ValueError(f"image shapes differ: test {t.shape}, reference {r.shape}")
    return t, r


def mse(test: np.ndarray, reference: np.ndarray) -> float:
    """Mean squared error over all pixels and channels, images scaled to [0, 1]."""
    t, r = _pair(test, reference)
    return float(np.mean((t - r) ** 2))


def psnr(test: np.ndarray, reference: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB (peak 1.0): ``10 log10(1 / MSE)``; ``inf`` for identical images."""
    m = mse(test, reference)
    return math.inf if m == 0.0 else float(10.0 * math.log10(1.0 / m))


def ssim_map(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-pixel SSIM (Wang et al. 2004, eq. 13) with a Gaussian window, averaged over channels.

    Returns
    -------
    (h, w) float64 in [-1, 1]; 1 where the images agree. Borders use
    reflection (scipy.ndimage ``mode='reflect'``).
    """
    from scipy.ndimage import gaussian_filter

    t, r = _pair(test, reference)
    c1, c2 = (SSIM_K1 * 1.0) ** 2, (SSIM_K2 * 1.0) ** 2
    sig = (SSIM_SIGMA, SSIM_SIGMA, 0.0)  # no blur across channels

    def blur(a):
        return gaussian_filter(a, sigma=sig, truncate=SSIM_TRUNCATE, mode="reflect")

    mu_t, mu_r = blur(t), blur(r)
    var_t = blur(t * t) - mu_t * mu_t
    var_r = blur(r * r) - mu_r * mu_r
    cov = blur(t * r) - mu_t * mu_r
    s = ((2 * mu_t * mu_r + c1) * (2 * cov + c2)) / ((mu_t ** 2 + mu_r ** 2 + c1) * (var_t + var_r + c2))
    return np.clip(s.mean(axis=2), -1.0, 1.0)


def ssim(test: np.ndarray, reference: np.ndarray) -> float:
    """Mean SSIM (Wang et al. 2004, eq. 17, MSSIM); exactly 1.0 for identical images."""
    t, r = _pair(test, reference)
    if np.array_equal(t, r):
        return 1.0
    return float(ssim_map(t, r).mean())


def flip_available() -> bool:
    """True when the ``flip-evaluator`` package can be imported."""
    try:
        import flip_evaluator  # noqa: F401
    except ImportError:
        return False
    return True


def flip(test: np.ndarray, reference: np.ndarray) -> tuple:
    """LDR-FLIP (Andersson et al. 2020) of ``test`` against ``reference``.

    Returns
    -------
    (mean_error, error_map) : float in [0, 1] (0 for identical images) and an
    (h, w, 3) float32 magma-coloured error map in [0, 1]; (None, None) when
    ``flip-evaluator`` is not installed.
    """
    if not flip_available():
        return None, None
    import flip_evaluator

    t, r = _pair(test, reference)
    t = np.ascontiguousarray(t[:, :, :3], np.float32)
    r = np.ascontiguousarray(r[:, :, :3], np.float32)
    err_map, mean, _ = flip_evaluator.evaluate(r, t, "LDR", applyMagma=True)
    mean = float(mean)
    if not math.isfinite(mean):
        raise FloatingPointError("FLIP returned a non-finite mean error")
    return mean, np.clip(np.asarray(err_map, np.float32), 0.0, 1.0)


def abs_error_map(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(h, w) float64 in [0, 1]: the largest absolute channel difference per pixel (the error map without FLIP)."""
    t, r = _pair(test, reference)
    return np.abs(t - r).max(axis=2)


def compare(test: np.ndarray, reference: np.ndarray) -> dict:
    """All metrics of one frame: ``psnr`` (dB, inf when identical), ``ssim``, ``flip`` (None without the package),
    ``identical`` (bool), and ``error_map`` ((h, w, 3) float32 in [0, 1]: FLIP's, else the absolute error in grey)."""
    t, r = _pair(test, reference)
    f, fmap = flip(t, r)
    if fmap is None:
        e = abs_error_map(t, r).astype(np.float32)
        fmap = np.repeat(e[:, :, None], 3, axis=2)
    return {"psnr": psnr(t, r), "ssim": ssim(t, r), "flip": f, "identical": bool(np.array_equal(t, r)),
            "error_map": fmap}


def flicker(prev: np.ndarray, cur: np.ndarray, ref_prev: np.ndarray, ref_cur: np.ndarray) -> float:
    """LOD flicker of one pair of consecutive frames: the temporal change the reference does not have.

    ``mean |(F_t - F_{t-1}) - (R_t - R_{t-1})|`` over pixels and channels, images
    in [0, 1]: motion that the full-detail reference also shows (walking,
    camera moves) cancels out; what remains is popping between LOD levels,
    splat shimmer and other changes the representation adds (the temporal
    error of the test sequence against the reference, in the spirit of
    Andersson et al.'s "alternating images" of FLIP, HPG 2020, §1, measured
    here in plain intensity).

    Parameters
    ----------
    prev, cur : (h, w, c) frames t-1 and t of the tested setting (uint8 or float in [0, 1])
    ref_prev, ref_cur : the reference's frames t-1 and t, same shape

    Returns
    -------
    float in [0, 2]; 0 when the setting changes exactly as the reference does.
    """
    a, b = _pair(cur, prev)
    c, d = _pair(ref_cur, ref_prev)
    if a.shape != c.shape:
        raise ValueError(f"image shapes differ: test {a.shape}, reference {c.shape}")
    return float(np.mean(np.abs((a - b) - (c - d))))
