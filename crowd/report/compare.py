"""``crowd report --compare BASELINE_DIR``: frame-time regressions against a baseline report beyond run-to-run noise.

Regression check (:func:`compare_reports`): each
setting runs ``--repeat N`` times (default 3 with ``--compare``, serially, never
two timed runs at once); a run's frame time is the median of its per-frame stage
sums and a setting's is the median of its runs' medians. Per (scene, setting
label) found in both reports, ``ratio = current / baseline`` and the noise of
each report is its relative spread ``1.4826 * MAD / median`` of the repeated
medians (MAD, the median absolute deviation, scaled to estimate a standard
deviation; robust to one slow run, e.g. a cold first run on a shared machine).
A regression is ``ratio > 1 + threshold`` with
``threshold = max(MIN_REGRESSION, NOISE_K * max(spread_current, spread_baseline))``
(5 % and 3: a slowdown must exceed three robust standard deviations of the
noisier report).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from crowd.errors import CrowdError

#: smallest relative slowdown flagged as a regression by ``--compare``
MIN_REGRESSION = 0.05
#: a slowdown must exceed NOISE_K times the larger relative spread (1.4826 MAD / median) of both reports
NOISE_K = 3.0
#: MAD -> standard deviation of a normal distribution
MAD_TO_SIGMA = 1.4826


def load_baseline(path) -> dict:
    """The report.json of a baseline report directory (``--compare``).

    Raises
    ------
    crowd.errors.CrowdError
        The directory has no readable report.json of a crowd report.
    """
    import json

    f = Path(path) / "report.json"
    try:
        data = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise CrowdError(f"--compare {path}: cannot read {f} ({type(e).__name__}); expected the directory of an "
                         f"earlier `crowd report` run") from None
    if not isinstance(data, dict) or not isinstance(data.get("scenes"), list):
        raise CrowdError(f"--compare {path}: {f} is not a crowd report (no 'scenes' list)")
    return data


def _timing(entry: dict) -> tuple:
    """(median ms, relative spread, runs) of a setting entry: the median of its repeated runs' median frame times
    and ``1.4826 * MAD / median`` of them (0 for one run; reports without repeats use their p50)."""
    meds = [float(x) for x in (entry.get("repeat_medians_ms") or []) if x is not None]
    if not meds:
        p50 = (entry.get("frame_ms") or {}).get("p50")
        meds = [float(p50)] if p50 is not None else []
    if not meds:
        return math.nan, math.nan, 0
    m = float(np.median(meds))
    mad = float(np.median(np.abs(np.asarray(meds) - m)))
    spread = MAD_TO_SIGMA * mad / m if m > 0 else 0.0
    return m, spread, len(meds)


def compare_reports(current: dict, baseline: dict, min_regression: float = MIN_REGRESSION,
                    noise_k: float = NOISE_K) -> list:
    """Frame-time comparison per (scene name, setting label) present in both reports.

    The rule (module docstring): ``ratio = median_current / median_baseline``;
    ``threshold = max(min_regression, noise_k * max(spread_current, spread_baseline))``;
    ``regression = ratio > 1 + threshold``.

    Returns
    -------
    list of dict: scene, label, current_ms, baseline_ms, ratio, spread_current,
    spread_baseline, threshold, runs_current, runs_baseline, regression (bool);
    settings without a counterpart in the baseline are left out.
    """
    base = {(sc.get("name"), st.get("label")): st for sc in baseline.get("scenes", [])
            for st in sc.get("settings", [])}
    rows = []
    for sc in current.get("scenes", []):
        for st in sc.get("settings", []):
            b = base.get((sc["name"], st["label"]))
            if b is None:
                continue
            mc, sc_, nc = _timing(st)
            mb, sb, nb = _timing(b)
            if not (math.isfinite(mc) and math.isfinite(mb) and mb > 0):
                continue
            ratio = mc / mb
            thr = max(min_regression, noise_k * max(sc_, sb))
            rows.append({"scene": sc["name"], "label": st["label"], "current_ms": mc, "baseline_ms": mb,
                         "ratio": ratio, "spread_current": sc_, "spread_baseline": sb, "threshold": thr,
                         "runs_current": nc, "runs_baseline": nb, "regression": bool(ratio > 1.0 + thr)})
    return rows
