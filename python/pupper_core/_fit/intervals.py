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
are fitted together, each one's own optimum is found from the fit's end
on its rows alone (``judge._own_shifts``), in the directions it places
alone (``placed``); where they
disagree by at least MODEL_RATIO times the noise interval, each interval
is widened to hold every log's own fit. (One step alone fell short: the
real hip's kp 5 log's own delay lay 5 % of the width past the interval.)"""

from __future__ import annotations

import math

import numpy as np

#: A segment's length (s): a stepped sine's step of 1 s, at least a few of the residual's correlation times.
SEGMENT_S = 1.0
#: Fewer segments than this over all logs give no sandwich (its spread would be noise itself).
MIN_SEGMENTS = 8
#: The sandwich must exceed the noise interval by this factor for some parameter to call the residual structure.
MODEL_RATIO = 2.0
#: A log alone places a direction where it holds at least this share of all the logs' information.
LOG_SHARE = 0.05


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


def placed(jac: np.ndarray, sizes: list[int]) -> list[np.ndarray] | None:
    """Per log, the projection onto the directions it places alone (a
    parameters x parameters matrix): a shift of its own fit along any other
    is the optimizer's wandering in a valley the log does not see; None with
    one log or rows that do not match."""
    if len(sizes) < 2 or jac is None or sum(sizes) != jac.shape[0]:
        return None
    # whitened by the whole fit's information H: in those coordinates each
    # log's own information H_i has eigenvalues in [0, 1], its share of what
    # all logs together know along each direction
    w, v = np.linalg.eigh(jac.T @ jac)
    if not np.all(np.isfinite(w)) or w[-1] <= 0:
        return None
    keep = w > w[-1] * 1e-12
    white, unwhite = v[:, keep] / np.sqrt(w[keep]), (v[:, keep] * np.sqrt(w[keep])).T
    out, start = [], 0
    for n in sizes:
        j = jac[start:start + n] @ white
        start += n
        share, u = np.linalg.eigh(j.T @ j)
        # a log alone places only the directions it knows a share of: along
        # one it hardly sees (damping against kd's scale at its one kd) its
        # "own optimum" is anywhere, and the other logs place it (no shift)
        seen = u[:, share >= LOG_SHARE]
        out.append(white @ seen @ seen.T @ unwhite)
    return out if all(np.all(np.isfinite(m)) for m in out) else None
