"""A joint's frequency response from a log of sines (``pupper_core._fit.validate``
compares the log's with the models'): stepped sines and chirps, from the
commanded angle to the measured one, at the recorded time stamps.

The commanded angle's upward zero crossings (about its median, the rest
angle) cut it into cycles; a cycle is a sine's when its downward crossing
lies near its middle and both halves swing. Over each cycle the Fourier
coefficient at the cycle's own frequency is taken of the command (held
between samples, as the servo holds it: integrated exactly) and of the
angle (its cycle mean removed; trapezoids between samples). The first
cycle of a step (a stepped sine's) is its transient and is dropped; the
cycles are then pooled by frequency (within POOL), the response of a pool
being the sum of its angle coefficients over the sum of its command's.
A multisine has no such cycles: it gives no response.

A step command (a square wave: the target holds still between jumps) is
told from the command itself (``jumps``) and read as steps instead
(``step_response``): per jump, the time the angle takes to cover RISE of
its own change (from the jump to where it settles: the mean of the last
SETTLED of the hold, so a servo's steady error is no slower rise) and its
overshoot past where it settles, averaged over the jumps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Cycles whose frequencies lie within this ratio are one step (and pooled).
POOL = 0.05
#: A half cycle must swing at least this fraction of the command's largest swing.
SWING = 0.1


@dataclass
class Response:
    """Frequency (Hz, increasing), gain (angle over command) and phase (deg,
    unwrapped from the lowest frequency) of a joint's response."""

    freq: np.ndarray
    gain: np.ndarray
    phase: np.ndarray
    #: the complex response at each frequency
    h: np.ndarray


def cycles(t: np.ndarray, x: np.ndarray) -> list[tuple[int, int, float]]:
    """The sine cycles of ``x`` (centred): (first sample, sample after the
    last, frequency Hz)."""
    top = float(np.max(np.abs(x))) if len(x) else 0.0
    if top <= 0:
        return []
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] > 0)) + 1
    down = np.flatnonzero((x[:-1] > 0) & (x[1:] < 0)) + 1

    def at(i: int) -> float:
        # the crossing between samples i-1 and i, linearly
        return float(t[i - 1] + (0 - x[i - 1]) * (t[i] - t[i - 1]) / (x[i] - x[i - 1]))

    out = []
    for a, b in zip(up[:-1], up[1:]):
        mid = down[(down > a) & (down < b)]
        if len(mid) != 1:
            continue
        ta, tb, td = at(int(a)), at(int(b)), at(int(mid[0]))
        if not 0.4 <= (td - ta) / (tb - ta) <= 0.6:
            continue
        if x[a:mid[0]].max() < SWING * top or -x[mid[0]:b].min() < SWING * top:
            continue
        out.append((int(a), int(b), 1.0 / (tb - ta)))
    return out


def _coefficients(t: np.ndarray, x: np.ndarray, y: np.ndarray, a: int, b: int, f: float) -> tuple[complex, complex]:
    """The Fourier coefficients at ``f`` of the held command ``x`` and the
    angle ``y`` over samples a..b."""
    w = 2 * math.pi * f
    ts, xs, ys = t[a:b + 1], x[a:b + 1], y[a:b + 1]
    e = np.exp(-1j * w * (ts - ts[0]))
    # x holds each sample's value until the next: its integral, exactly
    cx = complex(np.sum(xs[:-1] * (e[:-1] - e[1:])) / (1j * w))
    yc = ys - np.mean(ys)
    g = yc * e
    cy = complex(np.sum(0.5 * (g[:-1] + g[1:]) * np.diff(ts)))
    return cx, cy


def response(t: np.ndarray, command: np.ndarray, angle: np.ndarray) -> Response | None:
    """The response of ``angle`` to ``command`` (both at times ``t``), or
    None where the command holds no sine cycles."""
    x = command - np.median(command)
    cyc = cycles(t, x)
    if not cyc:
        return None
    kept = []
    for k, (a, b, f) in enumerate(cyc):
        prev = cyc[k - 1] if k else None
        nxt = cyc[k + 1] if k + 1 < len(cyc) else None
        new_step = prev is None or prev[1] != a or abs(prev[2] / f - 1) > POOL
        steady = nxt is not None and nxt[0] == b and abs(nxt[2] / f - 1) <= POOL
        if new_step and steady:
            # a step's first cycle: the joint is still settling into it
            continue
        kept.append((a, b, f, *_coefficients(t, x, angle, a, b, f)))
    kept.sort(key=lambda c: c[2])
    pools: list[list[tuple[int, int, float, complex, complex]]] = []
    for c in kept:
        if pools and c[2] <= pools[-1][0][2] * (1 + POOL):
            pools[-1].append(c)
        else:
            pools.append([c])
    freq = np.array([np.mean([c[2] for c in p]) for p in pools])
    h = np.array([sum(c[4] for c in p) / sum(c[3] for c in p) for p in pools])
    phase = np.degrees(np.unwrap(np.angle(h)))
    return Response(freq, np.abs(h), phase, h)


def bandwidth(r: Response) -> float:
    """The -3 dB bandwidth (Hz): where the gain first falls below its value
    at the lowest frequency over sqrt(2), interpolated in log frequency; NaN
    where it never does within the frequencies logged."""
    ref = float(r.gain[0]) / math.sqrt(2)
    below = np.flatnonzero(r.gain < ref)
    if not below.size or below[0] == 0:
        return math.nan
    i = int(below[0])
    lf = np.log(r.freq[i - 1:i + 1])
    g0, g1 = float(r.gain[i - 1]), float(r.gain[i])
    return float(np.exp(lf[0] + (g0 - ref) / (g0 - g1) * (lf[1] - lf[0])))


def phase_at(r: Response, f: float) -> float:
    """The phase (deg) at ``f``, interpolated in log frequency; within
    POOL past an end of the frequencies logged, that end's (a step of a
    stepped sine commanded at 2 Hz reads 2.0004 Hz off its stamps: it is
    the 2 Hz step, as its cycles are pooled); NaN further out."""
    if not r.freq[0] / (1 + POOL) <= f <= r.freq[-1] * (1 + POOL):
        return math.nan
    return float(np.interp(math.log(f), np.log(r.freq), r.phase))


def delay_left(log: Response, model: Response) -> float:
    """The pure delay (s) that best explains the log's phase lag behind the
    model's (positive: the log is later), by least squares over the common
    frequencies where the log's gain is at least a tenth of its largest."""
    common = [(f, hl, hm) for f, hl, hm, g in zip(log.freq, log.h, model.h, log.gain)
              if g >= 0.1 * float(np.max(log.gain))]
    if not common:
        return math.nan
    f = np.array([c[0] for c in common])
    lag = np.array([np.angle(c[2] / c[1]) for c in common])
    return float(np.sum(f * lag) / (2 * math.pi * np.sum(f * f)))


#: A step command jumps by at least JUMP of its swing at a time, and moves
#: by at most STILL of it between jumps, each hold HOLD samples or more:
#: a sine at the log's rate moves a little every sample, a stepped sine's
#: fast steps hold a sample or two.
JUMP = 0.1
STILL = 0.01
HOLD = 10
#: The share of a step's change the rise time is taken to.
RISE = 0.9
#: The share of a hold, at its end, whose mean angle is where the joint settled.
SETTLED = 0.2


@dataclass
class StepResponse:
    """The mean over a step command's jumps of the 90 % rise time (s) and
    the overshoot (% of the change); NaN where no jump could be read."""

    rise_time: float
    overshoot_pct: float
    jumps: int


def jumps(command: np.ndarray) -> np.ndarray | None:
    """The samples at which a step command jumps (the first of each new
    hold), or None where ``command`` is no step command."""
    swing = float(np.ptp(command)) if len(command) > 1 else 0.0
    if swing <= 0:
        return None
    d = np.abs(np.diff(command))
    at = np.flatnonzero(d >= JUMP * swing) + 1
    holds = np.diff(np.concatenate([[0], at, [len(command)]]))
    if not at.size or np.any((d > STILL * swing) & (d < JUMP * swing)) or holds.min() < HOLD:
        return None
    return at


def step_response(t: np.ndarray, command: np.ndarray, angle: np.ndarray) -> StepResponse | None:
    """The step response of ``angle`` to a step ``command`` (both at times
    ``t``), or None where ``command`` is no step command. A jump the joint
    does not follow (it moves under a tenth of the command's jump, or the
    other way) is not read."""
    at = jumps(command)
    if at is None:
        return None
    rises, overs = [], []
    for a, b in zip(at, np.append(at[1:], len(t))):
        y0 = float(angle[a - 1])
        change = float(np.mean(angle[b - max(1, int(SETTLED * (b - a))):b])) - y0
        if change * (command[a] - command[a - 1]) <= 0.1 * float(command[a] - command[a - 1]) ** 2:
            continue
        frac = (angle[a - 1:b] - y0) / change
        reach = np.flatnonzero(frac >= RISE)
        if not reach.size:
            continue
        i = int(reach[0])
        # the crossing, linearly between the samples either side (the jump's own sample: 0 of the change)
        tc = t[a - 2 + i] + (RISE - frac[i - 1]) / (frac[i] - frac[i - 1]) * (t[a - 1 + i] - t[a - 2 + i])
        rises.append(max(float(tc - t[a]), 0.0))
        overs.append(100.0 * max(float(np.max(frac)) - 1.0, 0.0))
    if not rises:
        return StepResponse(math.nan, math.nan, 0)
    return StepResponse(float(np.mean(rises)), float(np.mean(overs)), len(rises))
