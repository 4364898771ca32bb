"""Intervals that say what the residual is (``pupper_core._fit`` uses
them): noise, or structure the model cannot follow.

Gauss–Newton intervals assume the residual is the sensors' noise. On a
real motor it is mostly the model's error (a real Pupper bench log: 10 to
25 mrad of residual against an encoder that quantises to 0.1 mrad), which
the correlation-time widening does not cover: they claimed 7 digits of a
kp scale that moved by a third between fits of the same motor. Here the
residual's own spread decides: the logs are cut into segments
(SEGMENT_S each, a stepped sine's step), and the covariance of the
estimate is the block sandwich H⁻¹ (Σ_b g_b g_bᵀ) H⁻¹ (H = JᵀJ, g_b the
gradient Jᵀr of segment b's rows): what moving segments in or out of the
logs would do to where the fit ends, to first order — the limit of a
block bootstrap over the segments, without its draws (deterministic: the
same logs give the same intervals). Where that is at least MODEL_RATIO
times the noise interval for some parameter, the residual is structure,
not noise: the intervals are the wider of the two for each parameter,
and the fit says so.

Segments of one log share its gains: a model that bends differently at
other gains (on the real hip, a delay 1 ms longer and a kp scale 8 %
lower at kp 7.5 than at 5) shows it only between logs. Where several logs
are fitted together, each one's own fit is run from the fit's end on its
rows alone (``judge._own_shifts``); where they disagree by at least
MODEL_RATIO times the noise interval, each interval is widened to hold
every log's own fit. (A single Gauss–Newton step from the fit's end,
along the directions each log alone places, fell short of them: the
real hip's kp 5 log's own delay lay 5 % of the width past its interval.)"""

from __future__ import annotations

import math

import numpy as np

#: A segment's length (s): a stepped sine's step of 1 s, at least a few of the residual's correlation times.
SEGMENT_S = 1.0
#: Fewer segments than this over all logs give no sandwich (its spread would be noise itself).
MIN_SEGMENTS = 8
#: The sandwich must exceed the noise interval by this factor for some parameter to call the residual structure.
MODEL_RATIO = 2.0


def segments(times: list[np.ndarray], signals: int, period: float, tau: float) -> np.ndarray | None:
    """Each residual row's segment (every log's rows: its samples times the
    signals, signal fastest), or None where there are too few segments.
    ``period``: the samples' mean spacing; ``tau``: the residual's
    correlation time (samples): a segment spans at least 10 of them."""
    length = max(SEGMENT_S, 10 * tau * period)
    out, base = [], 0
    for t in times:
        rel = t - t[0]
        n = max(int(round(float(rel[-1]) / length)), 1)
        seg = np.minimum((rel / (float(rel[-1]) / n if rel[-1] > 0 else 1.0)).astype(int), n - 1)
        out.append(np.repeat(seg + base, signals))
        base += n
    if base < MIN_SEGMENTS:
        return None
    return np.concatenate(out)


def sandwich(jac: np.ndarray, r: np.ndarray, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The block sandwich covariance and its 95 % half-widths (Student's t
    over the segments less one), or None where H is singular or the rows
    do not match."""
    from scipy.special import stdtrit

    if jac is None or jac.shape[0] != r.shape[0] or seg.shape[0] != r.shape[0]:
        return None
    h = jac.T @ jac
    try:
        hinv = np.linalg.pinv(h)
    except np.linalg.LinAlgError:
        return None
    groups = int(seg.max()) + 1
    g = np.zeros((groups, jac.shape[1]))
    # each segment's share of the gradient J^T r
    np.add.at(g, seg, jac * r[:, None])
    meat = g.T @ g * groups / max(groups - 1, 1)
    cov = hinv @ meat @ hinv
    if not np.all(np.isfinite(cov)):
        return None
    half = float(stdtrit(max(groups - 1, 1), 0.975)) * np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return cov, half


def model_error(noise: np.ndarray, model: np.ndarray) -> bool:
    """Whether the segments' spread says the residual is structure: past
    MODEL_RATIO times the noise interval for some parameter."""
    ok = np.isfinite(noise) & np.isfinite(model) & (noise > 0)
    return bool(np.any(model[ok] >= MODEL_RATIO * noise[ok]))


def ratio(noise: np.ndarray, model: np.ndarray) -> float:
    ok = np.isfinite(noise) & np.isfinite(model) & (noise > 0)
    return float(np.max(model[ok] / noise[ok])) if np.any(ok) else math.nan
