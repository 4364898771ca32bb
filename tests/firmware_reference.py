"""A plain-Python firmware, written from the same description as the Rust
core's (crates/pupper_core/src/sim/replay.rs and firmware.rs), as an
oracle for `pupper fit`'s replay (issue 60: the fit's replay runs the
Rust core's firmware; this is the Python arithmetic it replaced, kept
here only to hold the two together)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from pupper_core._fit.replay import DELAY_SLOT, KD_SLOT, KP_SLOT, LAG_SLOT, LATENCY_SLOT, _components

class _RefState:
    """The firmware of a batch of rollouts: per rollout and actuator the
    held torque, the last encoder angle and the filtered derivative."""

    def __init__(self, fw: Any, shape: tuple[int, int], dt: float, sign: np.ndarray | None = None) -> None:
        self.fw = fw
        #: each rollout's sign of the noise it reads (antithetic pairs)
        self.sign = np.ones((shape[0], 1)) if sign is None else sign
        self.period = 1 / fw.rate if fw.rate else dt
        self.alpha = 1 - math.exp(-2 * math.pi * fw.filter * self.period) if fw.filter else None
        self.held = np.zeros(shape)
        self.last = np.full(shape, math.nan)
        self.filtered = np.full(shape, math.nan)
        self.updates = 0
        self.draws = np.random.default_rng(fw.seed)

    def due(self, t: float) -> bool:
        due = self.fw.rate is None or t * self.fw.rate + 1e-6 >= self.updates
        self.updates += int(due)
        return due

    def update(self, kp: np.ndarray, kd: np.ndarray, target: np.ndarray, q: np.ndarray, v: np.ndarray) -> None:
        if self.fw.noise:
            # common random numbers: every rollout reads the same noise, so the replay stays smooth in the
            # parameters while the PD is dithered as the hardware's is
            q = q + self.sign * self.fw.noise * np.asarray(self.draws.standard_normal(q.shape[1]))[None, :]
        if self.fw.counts:
            # the encoder's difference velocity; its rounding is not replayed: a rounded angle makes the
            # replay a staircase in the parameters, which no finite-difference Jacobian can follow
            v = np.where(np.isnan(self.last), v, (q - self.last) / self.period)
            self.last = q
        if self.alpha is not None:
            self.filtered = np.where(np.isnan(self.filtered), v, self.filtered + self.alpha * (v - self.filtered))
            v = self.filtered
        self.held = kp * (target - q) - kd * v

    def deliver(self, peak: np.ndarray, speed: np.ndarray) -> np.ndarray:
        if self.fw.noload:
            hi = np.clip(peak * (1 - speed / self.fw.noload), -peak, peak)
            lo = np.clip(peak * (-1 - speed / self.fw.noload), -peak, peak)
        else:
            hi, lo = peak, -peak
        return np.minimum(np.maximum(self.held, lo), hi)




def _all_delayed(control: np.ndarray, lag: np.ndarray) -> np.ndarray:
    """Every step's ``_delayed`` target at once (rollouts, steps, actuators)."""
    n = control.shape[1]
    at = np.maximum(np.arange(n)[None, :, None] - lag[:, None, :], 0.0)
    i0 = np.floor(at).astype(int)
    frac = at - i0
    i1 = np.minimum(i0 + 1, np.arange(n)[None, :, None])
    b = np.arange(control.shape[0])[:, None, None]
    a = np.arange(control.shape[2])[None, None, :]
    return np.asarray(control[b, i0, a] * (1 - frac) + control[b, i1, a] * frac)


def _delayed(control: np.ndarray, k: int, lag: np.ndarray) -> np.ndarray:
    """Each rollout's and actuator's target ``lag`` steps before step k,
    linearly between steps (the first target before the start)."""
    at = np.maximum(k - lag, 0.0)
    i0 = np.floor(at).astype(int)
    frac = at - i0
    i1 = np.minimum(i0 + 1, k)
    b = np.arange(control.shape[0])[:, None]
    a = np.arange(control.shape[2])[None, :]
    return np.asarray(control[b, i0, a] * (1 - frac) + control[b, i1, a] * frac)





def _ref_actuators(fw: Any, models: list[Any], dt: float) -> tuple[np.ndarray, ...]:
    """Each rollout's kp, kd, command delay and latency in steps, torque
    limit, and the share of the way the torque follows the PD per step."""
    kp, kd, lag, latency, tlag = (np.stack([m.actuator_gainprm[:, s] for m in models])
                                  for s in (KP_SLOT, KD_SLOT, DELAY_SLOT, LATENCY_SLOT, LAG_SLOT))
    lag = lag / dt
    latency = np.maximum(latency / dt - (0.25 if fw.rate is None else 0.0), 0.0)
    peak = np.stack([np.where(m.actuator_forcelimited.astype(bool), np.abs(m.actuator_forcerange).max(axis=1),
                              np.inf) for m in models])
    follow = np.where(tlag > 0, -np.expm1(-dt / np.maximum(tlag, 1e-12)), 1.0)
    return kp, kd, lag, latency, peak, follow

def reference_replay(fw: Any, models: list[Any], control: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each rollout's state and sensors through the firmware ``fw``; with noise, the mean of an
    antithetic pair (the noise read, and its negative): the response to
    the noise itself, which no replay can match to the hardware's own
    draw, cancels to first order, and what the noise does to the
    friction (it dithers the joint loose) stays."""
    import mujoco
    import mujoco.batch

    nb = len(models)
    if fw.noise:
        models, control, x0 = models * 2, np.concatenate([control, control]), np.concatenate([x0, x0])
    nb2, n, nu = control.shape
    m0 = models[0]
    dt = float(m0.opt.timestep)
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    # every rollout stepped by one call on all cores (bit for bit a loop over one MjData each)
    batch = mujoco.batch.Batch(m0, nb2, nthread=0)
    batch.set_models(models)
    batch.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
    rows, full = batch.state, _components(m0, kind, mujoco.mjtState.mjSTATE_INTEGRATION)
    rows[:, full] = x0
    ctrls = batch.bind("ctrl")
    jnt = m0.actuator_trnid[:, 0]
    qadr, dadr = m0.jnt_qposadr[jnt], m0.jnt_dofadr[jnt]
    kp, kd, lag, latency, peak, follow = _ref_actuators(fw, models, dt)
    lagged = np.any(follow < 1.0)
    felt = np.any(latency > 0)
    qh = np.empty((nb2, n, nu)) if felt else None
    vh = np.empty((nb2, n, nu)) if felt else None
    out = np.zeros((nb2, nu))
    state = np.empty((nb2, n, mujoco.mj_stateSize(m0, kind)))
    delivered = np.empty((nb2, n, nu))
    sign = np.where(np.arange(nb2) < nb, 1.0, -1.0)[:, None]
    fs = _RefState(fw, (nb2, nu), dt, sign)
    # the torque the PD gives on the replay's own angle, without the noise it reads: what the
    # torque sensors report (the hardware's dither is its own draw, which no replay can match)
    clean = _RefState(replace(fw, noise=None), (nb2, nu), dt) if fw.noise else None
    # the angles and velocities read back from the state each step records (time, qpos, qvel first)
    qcol = 1 + qadr
    vcol = 1 + mujoco.mj_stateSize(m0, mujoco.mjtState.mjSTATE_QPOS) + dadr
    clean_out = np.zeros((nb2, nu))
    # the command `delay` ago at every step, once
    targets = _all_delayed(control, lag)
    for k in range(n):
        now = x0 if k == 0 else state[:, k - 1]
        q, v = now[:, qcol], now[:, vcol]
        speed = v
        if qh is not None and vh is not None:
            # what the PD reads is `latency` old (the state before the log's start held still)
            qh[:, k], vh[:, k] = q, v
            q, v = _delayed(qh, k, latency), _delayed(vh, k, latency)
        if fs.due(k * dt):
            target = targets[:, k]
            fs.update(kp, kd, target, q, v)
            if clean is not None:
                clean.update(kp, kd, target, q, v)
        tau = fs.deliver(peak, speed)
        if lagged:
            # the current loop follows the PD's torque with a first-order lag
            out += follow * (tau - out) if k else tau - out
            tau = out
        delivered[:, k] = tau
        ctrls[:] = tau
        batch.step()
        state[:, k] = rows[:, full]
        if clean is not None:
            torque = clean.deliver(peak, speed)
            if lagged:
                clean_out += follow * (torque - clean_out) if k else torque - clean_out
                torque = clean_out
            delivered[:, k] = torque
    # the sensors (each actuator's angle, velocity and torque: ``suspended_spec``'s), as MuJoCo reads them
    # at each step's start (the state before it), and the torques delivered, once for every step
    before = np.concatenate([x0[:, None], state[:, :-1]], axis=1)
    sens = np.concatenate([before[:, :, qcol], before[:, :, vcol], delivered], axis=2)
    if nb2 > nb:
        return 0.5 * (state[:nb] + state[nb:]), 0.5 * (sens[:nb] + sens[nb:])
    return state, sens
