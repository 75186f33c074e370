"""The cost model of mode auto, fitted online to the frames it draws (issue 26, item 1).

Every frame the engine reports what it drew (the counts of :func:`lod.auto.cost_model.features`, extended
by what other draw paths add to ``DrawList.stats``) and how long the rendering took. The per-unit costs are
the coefficients ``c`` of the linear frame model of :mod:`lod.auto.cost_model` (Funkhouser & Séquin 1993,
§4.1), estimated by Bayesian linear regression with exponential forgetting (recursive least squares,
Ljung & Söderström 1983, in information form), with the machine's calibration (``crowd calibrate``; the
defaults when there is none) as a Gaussian prior:

- **Parameters.** ``c_j = s_j θ_j`` with ``s_j`` the prior's coefficient (the default where the prior has
  none or 0), so every ``θ_j`` is of order one and a frame's row ``u = s ∘ x / y`` (counts scaled by the
  prior's costs, divided by the measured seconds ``y``) has entries of order one: the fit minimises
  *relative* error, and a slow frame does not outweigh a fast one.
- **Prior.** ``θ ~ N(θ0, Σ0)`` with ``Σ0 = σ_g² θ0 θ0ᵀ + diag(σ_j²)``: one almost free common scale
  (``σ_g`` = :data:`SCALE_SD`: a calibration from a busy or another machine is off by a factor for every
  unit alike, and the load changes that factor) and per-unit departures from the calibration's ratios
  (``σ_j`` = :data:`UNIT_SD` of a real calibration, :data:`NEUTRAL_SD` of the defaults and of a count the
  calibration does not know, :data:`FRAME_SD` of the constant per frame, which depends on the viewport). Its weight is a few frames' worth. A feature that never varies, or is
  collinear with others, stays where the prior and the common scale put it (the posterior's ridge).
- **Data.** ``A ← λ A + w u uᵀ``, ``b ← λ b + w u`` (target 1 per row), forgetting factor ``λ`` =
  :data:`FORGET` (about 30 frames of memory: the view and the load move). The prior is not forgotten, so a
  direction no recent frame excites returns to the prior scaled by the common factor the recent frames
  measured, and its uncertainty grows back: that is what makes auto try a representation it has not drawn
  for a while (:mod:`lod.auto.control`).
- **Load.** A change of the machine's load (a second process starting) makes every cost alike dearer; the
  fit follows it through its forgetting, and until it has, a factor ``g`` bridges the gap: the median of
  measured / fitted over the last :data:`LOAD_FRAMES` frames (a single noisy frame does not move it). Predictions
  are multiplied by it and residuals (noise, Huber weights) taken after it, so the frames after a change keep
  their full weight; ``g`` returns to 1 as the fit catches up. A factor that stays beyond ``1 ±``
  :data:`LOAD_SHIFT` for :data:`LOAD_FRAMES` frames is a change point: the data before it keep the weight
  :data:`SHIFT_FORGET` only, so the fit follows the new load within a few more frames. (Dividing the rows by ``g`` instead would make
  ``(θ c, g / c)`` indistinguishable and let ``g`` wander with the mix of the recent frames.)
- **Noise.** The relative noise ``σ`` is the robust spread (1.4826 median absolute value) over the last
  :data:`NOISE_FRAMES` frames of each frame's log residual under the current fit less the median of the
  :data:`LOAD_FRAMES` before it (what the load factor would have predicted: a change of load is not noise),
  scaled by ``sqrt(n / (n - p))`` for the ``p`` parameters the data determine (``tr(P⁻¹ A) / σ²``), so that a
  fit of few rows does not believe itself exact. A row whose standardised residual exceeds :data:`HUBER_K` is down-weighted
  to ``w = HUBER_K / |e|`` (Huber 1964): one frame 3x slower because another process ran does not move the
  fit far.
- **Posterior.** ``P = Σ0⁻¹ + A / σ²``, mean ``μ = P⁻¹ (Σ0⁻¹ θ0 + b / σ²)``, projected onto ``θ >= 0`` in the
  metric ``P`` (:func:`_project`: the negative costs held at 0, the others at their conditional mean) so that
  no cost is negative. A prediction for counts
  ``x`` is ``g s ∘ x · μ`` with the variance ``g² zᵀ P⁻¹ z`` (``z = s ∘ x``) of its mean, the frame's own
  noise ``σ²·pred²`` on top.

Pure numpy/scipy (``lod`` imports only ``sim``); a dozen features, so the update and the solve are a few
tens of microseconds per frame.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from lod.auto import cost_model as cm

#: forgetting factor of the data (per frame): ~1 / (1 - λ) = 33 frames of memory
FORGET = 0.97
#: prior standard deviation of the common scale of all costs (relative): free (every frame measures it; the
#: defaults on a machine 70x slower under load are that far off)
SCALE_SD = 100.0
#: prior standard deviation of one per-unit cost relative to the calibration's ratios (a real calibration)
UNIT_SD = 0.5
#: the same for the defaults (no calibration of this machine) and for counts no calibration knows
NEUTRAL_SD = 1.0
#: a load factor beyond 1 +- this for LOAD_FRAMES frames is a change of load: the data so far are kept with
#: weight SHIFT_FORGET only (the fit then follows the new load within a few frames)
LOAD_SHIFT = 0.15
SHIFT_FORGET = 0.25
#: the same for the constant per frame
FRAME_SD = 2.0
#: rows whose residuals give the noise estimate (the most recent)
NOISE_FRAMES = 32
#: frames the load factor is the median over
LOAD_FRAMES = 5
#: noise floor and start value (relative)
NOISE_MIN = 0.02
NOISE_START = 0.25
#: standardised residual beyond which a row is down-weighted (Huber)
HUBER_K = 2.5


def _project(P: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The non-negative θ closest to ``mu`` in the metric ``P`` (the posterior's), by an active set that only
    grows: the costs that come out negative are held at 0 and the others take the conditional mean
    ``θ_F = μ_F + P_FF⁻¹ P_FA μ_A``, until none is negative (a dozen features: one or two rounds)."""
    active = mu < 0.0
    out = mu.copy()
    for _ in range(mu.shape[0]):
        free = ~active
        out = np.zeros_like(mu)
        if free.any():
            out[free] = mu[free] + np.linalg.solve(P[np.ix_(free, free)], P[np.ix_(free, active)] @ mu[active])
        neg = free & (out < 0.0)
        if not neg.any():
            break
        active |= neg
    return np.maximum(out, 0.0)


class OnlineCostModel:
    """Per-unit frame costs fitted online with a calibration as prior (module docstring).

    Parameters
    ----------
    prior : :class:`lod.auto.cost_model.CostModel` (``is_default``: the neutral prior)
    names : feature names in column order (default :data:`lod.auto.cost_model.ONLINE_FEATURES`); the
        constant ``frame`` comes first
    forget : λ in (0, 1]
    """

    def __init__(self, prior=None, names=cm.ONLINE_FEATURES, forget: float = FORGET):
        prior = prior if prior is not None else cm.CostModel()
        if not (0.0 < float(forget) <= 1.0):
            raise ValueError(f"online cost model: forgetting factor must be in (0, 1], got {forget}")
        self.prior = prior
        self.names = ("frame",) + tuple(names)
        self.forget = float(forget)
        pc = prior.coefficients
        neutral = bool(getattr(prior, "is_default", True))
        c0 = np.array([float(pc.get(n, 0.0)) for n in self.names], np.float64)
        dflt = np.array([cm.DEFAULTS.get(n, cm.EXTRA_DEFAULTS.get(n, 1e-6)) for n in self.names], np.float64)
        known = np.array([n in pc for n in self.names])
        #: the scale s_j of every coefficient (seconds per unit)
        self.scale = np.where(c0 > 0.0, c0, dflt)
        self.theta0 = np.where(known, c0 / self.scale, 1.0)
        sd = np.where(known & ~neutral, UNIT_SD, NEUTRAL_SD)
        sd[0] = FRAME_SD  # the constant: clearing and resolving depend on the viewport, which the calibration fixes
        cov0 = SCALE_SD ** 2 * np.outer(self.theta0, self.theta0) + np.diag(sd ** 2)
        self.P0 = np.linalg.inv(cov0)
        self.P0 = 0.5 * (self.P0 + self.P0.T)
        self.h0 = self.P0 @ self.theta0
        n = len(self.names)
        self.A = np.zeros((n, n))
        self.b = np.zeros(n)
        self.noise = NOISE_START
        #: the common factor of the current load (measured / fitted of the last :data:`LOAD_FRAMES` frames)
        self.load = 1.0
        self._shift = 0  # consecutive frames the load factor stayed off 1 by more than LOAD_SHIFT
        self.frames = 0  # rows accepted
        self._rows: deque = deque(maxlen=NOISE_FRAMES)  # (z, seconds) of the last frames
        self._solve()

    # ------------------------------------------------------------------------------------------ fitting
    def _solve(self) -> None:
        s2 = self.noise ** 2
        P = self.P0 + self.A / s2
        P = 0.5 * (P + P.T)
        try:
            L = np.linalg.cholesky(P)
        except np.linalg.LinAlgError:  # cannot happen with a positive definite prior; keep the last fit
            return
        Li = np.linalg.inv(L)  # a dozen features: the explicit inverse is cheaper than repeated solves
        Pinv = Li.T @ Li
        mu = Pinv @ (self.h0 + self.b / s2)
        if (mu < 0.0).any():
            mu = _project(P, mu)
        self.P = P
        self._Pinv = Pinv
        self.mu = mu

    def row(self, counts) -> np.ndarray:
        """``z = s ∘ [1, counts]``: a frame's counts in the fit's units (predicted seconds per term under the
        prior's scales); ``counts`` in :attr:`names` order without the constant (shorter: zeros appended)."""
        x = np.zeros(len(self.names))
        x[0] = 1.0
        c = np.asarray(counts, np.float64).reshape(-1)[: len(self.names) - 1]
        x[1:1 + c.shape[0]] = c
        return self.scale * x

    def update(self, counts, seconds: float) -> float | None:
        """Add a measured frame: ``counts`` (:meth:`row`'s input), ``seconds`` of rendering.

        Returns the standardised residual of the frame under the fit before it (None: rejected, non-finite
        or non-positive input)."""
        y = float(seconds)
        z = self.row(counts)
        if not (math.isfinite(y) and y > 0.0 and np.isfinite(z).all() and (z >= 0.0).all()):
            return None
        u = z / y  # relative to the measurement: 1 is a perfect prediction
        pred, var = self._pred_var(u)
        if not (math.isfinite(pred) and pred > 0.0):
            return None
        g = self.load  # residuals after the load bridge: frames after a change of load keep their weight
        e = (1.0 - g * pred) / math.sqrt(self.noise ** 2 * (g * pred) ** 2 + g * g * var + 1e-12)
        w = 1.0 if abs(e) <= HUBER_K else HUBER_K / abs(e)
        lam = self.forget
        self.A = lam * self.A + w * np.outer(u, u)
        self.b = lam * self.b + w * u
        self._rows.append((z, y))
        self.last_z, self.last_u = z, u  # the row as the fit took it (lod.auto.control keeps it per plan)
        self.frames += 1
        if self.frames < 2 * NOISE_FRAMES or self.frames % 4 == 0:  # it changes little from frame to frame
            self._noise()  # with the fit before this row, then one solve
        self._solve()
        # the load: the median over the last few frames of measured / fitted (one noisy frame does not move it)
        if len(self._rows) >= 3:
            k = len(self._rows)
            recent = [self._rows[i] for i in range(max(0, k - LOAD_FRAMES), k)]
            ratios = sorted(yy / max(float(zz @ self.mu), 1e-12) for zz, yy in recent)
            m = len(ratios)
            self.load = ratios[m // 2] if m % 2 else 0.5 * (ratios[m // 2 - 1] + ratios[m // 2])
            # a load that stays off the fit: a change point, old frames measured another machine state
            self._shift = self._shift + 1 if abs(math.log(self.load)) > math.log(1.0 + LOAD_SHIFT) else 0
            if self._shift >= LOAD_FRAMES and self.frames > 2 * LOAD_FRAMES:
                self.A *= SHIFT_FORGET
                self.b *= SHIFT_FORGET
                self._shift = 0
                self._solve()
        return float(e)

    def _noise(self) -> None:
        """Re-estimate the relative noise from the recent frames (module docstring)."""
        n_rows = len(self._rows)
        if n_rows < LOAD_FRAMES + 4:
            return
        Z = np.array([z for z, _ in self._rows])
        y = np.array([y for _, y in self._rows])
        r = np.log(y / np.maximum(Z @ self.mu, 1e-12))
        # each residual less the median of the LOAD_FRAMES before it (one vectorised median)
        win = np.lib.stride_tricks.sliding_window_view(r[:-1], LOAD_FRAMES)
        d = r[LOAD_FRAMES:] - np.median(win, axis=1)
        n = d.shape[0]
        p_eff = float(np.einsum("ij,ji->", self._Pinv, self.A)) / self.noise ** 2  # parameters the data fix
        dof = max(n - min(p_eff, n - 1.0), 1.0)
        self.noise = float(max(NOISE_MIN, 1.4826 * np.median(np.abs(d)) * math.sqrt(n / dof)))

    # ------------------------------------------------------------------------------------------ predictions
    def _pred_var(self, z) -> tuple[float, float]:
        return float(z @ self.mu), float(z @ self._Pinv @ z)

    def predict(self, counts) -> tuple[float, float]:
        """(seconds at the current load, standard deviation of that mean) for ``counts``."""
        m, v = self._pred_var(self.row(counts))
        return self.load * m, self.load * math.sqrt(max(v, 0.0))

    def predict_z(self, z) -> float:
        """Seconds at the current load for a row in the fit's units (:meth:`row`)."""
        return self.load * float(np.asarray(z) @ self.mu)

    def relative(self, u) -> float:
        """Predicted / measured of a frame's row over its seconds (``z / y``) under the current fit and load."""
        return self.load * float(np.asarray(u) @ self.mu)

    def sd_z(self, z) -> float:
        """Standard deviation (seconds at the current load) of the predicted mean of a row ``z`` (or of a
        difference of rows)."""
        return self.load * math.sqrt(max(self._pred_var(np.asarray(z, np.float64))[1], 0.0))

    @property
    def coefficients(self) -> dict:
        """name -> seconds per unit at the current load (the posterior mean, >= 0)."""
        return {n: float(v) for n, v in zip(self.names, self.load * self.scale * self.mu)}

    @property
    def sd(self) -> dict:
        """name -> posterior standard deviation of each per-unit cost (seconds per unit at the current load)."""
        d = np.sqrt(np.maximum(np.diag(self._Pinv), 0.0))
        return {n: float(v) for n, v in zip(self.names, self.load * self.scale * d)}

    def cost_model(self, raster_share: float = 0.0):
        """The posterior mean as a :class:`lod.auto.cost_model.CostModel` (the coefficients the candidates
        price options with), keyed as the prior. ``raster_share``: the share of the triangles the renderer
        rasterises in compute (:class:`RouteShare`); a triangle is priced at the two paths' costs mixed so."""
        c = self.coefficients
        out = {k: c[k] for k in cm.COEFFICIENTS}
        s = min(1.0, max(0.0, float(raster_share)))
        out["triangles"] = (1.0 - s) * c["triangles"] + s * c.get("raster_triangles", c["triangles"])
        return cm.CostModel(out, key=self.prior.key, samples=self.frames)



    def state(self) -> dict:
        """What :mod:`crowd.explain` prints: per-unit costs and their prior, the noise, frames fitted."""
        pc = self.prior.coefficients
        return {"coefficients": self.coefficients, "sd": self.sd,
                "prior": {n: float(pc[n]) if n in pc else None for n in self.names},
                "noise": float(self.noise), "load": float(self.load), "frames": int(self.frames)}


class RouteShare:
    """The share of a frame's triangles the renderer rasterises in compute (``render/raster/``, routed per copy by
    :mod:`lod.raster_route`), as the frames drawn measured it (``DrawList.stats["raster_triangles"]`` after the
    draw, of ``stats["triangles"]``), smoothed over frames by :data:`ROUTE_SMOOTHING`.

    The selection counts every triangle as a triangle; the renderer then sends the small ones to the compute
    path, and the fit learns each path's cost from the frames as drawn. Without the share, a plan's triangles
    were priced at the hardware path's cost alone: on a view whose triangles all go to compute, that cost is
    never measured, the fit may hold it at 0, and auto then took full detail for free (a frame 4.6x its
    prediction, tests/crowd/test_fly_settle.py). With it, options and plans price a triangle at the two paths'
    costs in the proportion drawn (:meth:`OnlineCostModel.cost_model`), and a selection's counts are split so
    before they are predicted (:meth:`split`)."""

    def __init__(self):
        self.share = 0.0
        self._seen = False

    def observe(self, stats) -> None:
        """A drawn frame's ``DrawList.stats`` (after the renderer's draw)."""
        try:
            tri = float(stats.get("triangles", 0) or 0)
            ras = float(stats.get("raster_triangles", 0) or 0)
        except (AttributeError, TypeError, ValueError):
            return
        if not (math.isfinite(tri) and math.isfinite(ras) and tri > 0.0):
            return
        s = min(1.0, max(0.0, ras / tri))
        self.share = s if not self._seen else ROUTE_SMOOTHING * self.share + (1.0 - ROUTE_SMOOTHING) * s
        self._seen = True

    def split(self, x) -> np.ndarray:
        """Extended counts (:func:`lod.auto.cost_model.features`) of a selection not drawn yet, its triangles
        divided between the paths by the share (a list that already names its compute triangles is left)."""
        x = np.asarray(x, np.float64).copy()
        i = len(cm.FEATURES) + cm.EXTRA_FEATURES.index("raster_triangles")
        if x.shape[0] > i and x[i] == 0.0 and self.share > 0.0:
            x[i] = self.share * x[0]
            x[0] -= x[i]
        return x


#: weight of the share so far against the last frame's (per frame)
ROUTE_SMOOTHING = 0.5

__all__ = ["OnlineCostModel", "RouteShare", "FORGET", "LOAD_FRAMES", "SCALE_SD", "UNIT_SD", "NEUTRAL_SD", "NOISE_FRAMES", "HUBER_K"]
