"""`pupper fit --motor`: the replay through the servo firmware
(``pupper_core._fit`` fits through it), as torque mode's Rust firmware runs
it (crates/pupper_core/src/sim/firmware.rs): the PD updated at the
firmware's rate on the encoder's angle (quantised to ``counts``) and its
difference over an update period, a first-order derivative filter, the
command ``delay`` ago, the torque held between updates and delivered within
the torque limit (falling with speed to 0 at ``noload``).

The motor is MuJoCo's: the actuators become plain torque motors; the
fitted gains and delay ride in each motor's unused gain parameters
(gainprm[1]: kp, [2]: kd, [3]: the command delay), which the parameters'
modifiers set, so that each rollout of a Jacobian carries its own."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from pupper_core._fit.terms import FitError

#: --motor's keys fit replays (the delay is fit's own parameter).
KEYS = ("rate", "filter", "counts", "noload", "noise")
#: The other draws of the noise the intervals replay the fit's end through
#: (``pupper_core._fit._intervals``): the fit follows its one draw, and where
#: it ends moves with it by as much as the hardware's own noise moves it.
DRAWS = 12
#: Where a firmware motor keeps the PD's kp, kd, command delay, the feedback latency (how old the
#: angle and velocity the PD reads are) and the torque's lag (a first-order filter behind the PD).
KP_SLOT, KD_SLOT, DELAY_SLOT, LATENCY_SLOT, LAG_SLOT = 1, 2, 3, 4, 5
#: How much later (steps) a PD updated every physics step and held over it acts than a continuous one
#: (``_actuators``): a quarter step under MuJoCo's semi-implicit Euler.
HELD_STEPS = 0.25


@dataclass
class Firmware:
    rate: float | None = None
    filter: float | None = None
    counts: int | None = None
    noload: float | None = None
    #: the encoder's noise (rad, 1 sigma) the PD reads: one seeded draw, the same in every rollout
    noise: float | None = None
    #: the seed of that draw (0; the intervals replay a few others, ``DRAWS``)
    seed: int = 0

    def spec(self) -> str:
        return ",".join(f"{k}={getattr(self, k):g}" for k in KEYS if getattr(self, k) is not None)


def parse_motor(text: str | None, dt: float) -> Firmware | None:
    """--motor's text (KEY=VALUE,...): None for the ideal motor (MuJoCo's
    servo, as without --motor)."""
    if text is None or not text.strip() or text.strip() == "ideal":
        return None
    fw = Firmware()
    seen: set[str] = set()
    for part in (p.strip() for p in text.split(",")):
        key, eq, value = part.partition("=")
        key = key.strip()
        if key == "delay":
            raise FitError("--motor delay=...: fit's command delay is its parameter 'delay' (fitted, or held at 0 "
                           "when left out of --params): drop delay= from --motor")
        if not eq or key not in KEYS:
            raise FitError(f"--motor item '{part}' is not KEY=VALUE with KEY one of {', '.join(KEYS)}: write e.g. "
                           "--motor rate=500,counts=16384")
        if key in seen:
            raise FitError(f"--motor gives '{key}' twice: keep one value")
        seen.add(key)
        try:
            v = float(value) if key != "counts" else int(value)
        except ValueError:
            raise FitError(f"--motor {key}={value} is not a {'whole ' if key == 'counts' else ''}number") from None
        if not (math.isfinite(v) and v > 0) or (key == "counts" and v < 2):
            raise FitError(f"--motor {key}={value} must be {'>= 2' if key == 'counts' else '> 0 and finite'}")
        setattr(fw, key, v)
    if fw.rate is not None and fw.rate * dt > 1 + 1e-9:
        raise FitError(f"--motor rate={fw.rate:g} Hz is faster than the physics ({1 / dt:g} Hz): give a rate at "
                       "or below it")
    return fw


class _State:
    """The firmware of a batch of rollouts: per rollout and actuator the
    held torque, the last encoder angle and the filtered derivative."""

    def __init__(self, fw: Firmware, shape: tuple[int, int], dt: float, sign: np.ndarray | None = None) -> None:
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


def _components(model: Any, part: int, whole: int) -> np.ndarray:
    """Where the state vector ``part`` (an mjtState spec) sits within the
    vector ``whole`` that holds it: components are laid out in the order of
    their bits, each as long as ``mj_stateSize`` says."""
    import mujoco

    at, out = 0, []
    bit = 1
    while bit <= int(whole):
        if int(whole) & bit:
            size = mujoco.mj_stateSize(model, bit)
            if int(part) & bit:
                out.extend(range(at, at + size))
            at += size
        bit <<= 1
    return np.asarray(out, dtype=np.intp)


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


def rollout_fn(sysid: Any, fw: Firmware) -> Any:
    """sysid's custom rollout through the firmware: every rollout of a call
    stepped together, the firmware's arithmetic batched over them."""
    from mujoco.sysid._src.trajectory import arrays2traj, sequence2array, timeseries2array

    def rollout(**kw: Any) -> Any:
        control, control_times = timeseries2array(kw["control_signal"])
        x0 = sequence2array(kw["initial_states"])
        state, sens = _replay(fw, list(kw["models"]), control, x0)
        return arrays2traj(kw["models"], x0, control, control_times, state, sens, kw["rollout_signal_mapping"],
                           kw["rollout_state_mapping"], kw["ctrl_mapping"])

    return rollout


def _actuators(fw: Firmware, models: list[Any], dt: float) -> tuple[np.ndarray, ...]:
    """Each rollout's actuator parameters as the replay steps them: kp, kd,
    the command delay and the PD's latency in steps, the torque limit, and
    the share of the way the torque follows the PD per step (1: no lag)."""
    kp, kd, lag, latency, tlag = (np.stack([m.actuator_gainprm[:, s] for m in models])
                                  for s in (KP_SLOT, KD_SLOT, DELAY_SLOT, LATENCY_SLOT, LAG_SLOT))
    lag = lag / dt
    # the PD reads the state `latency` old; updated every physics step and held over it, it acts later
    # than a continuous PD would: a firmware without a rate of its own stands for a continuous one, so it
    # reads younger. By a quarter step, not half: MuJoCo's semi-implicit Euler moves the angle by a held
    # torque's whole step at once (twice a held torque's exact first-step motion), so a held torque acts
    # half as late as it is held. A stand stepped at 0.1 ms with 3 and 6 ms of latency, at kp 5 and 7.5,
    # is replayed best at its own latency with a quarter step; with half, 0.5 to 0.75 ms too long
    latency = np.maximum(latency / dt - (HELD_STEPS if fw.rate is None else 0.0), 0.0)
    # each rollout's own torque limit (a fitted one differs between a Jacobian's rollouts)
    peak = np.stack([np.where(m.actuator_forcelimited.astype(bool), np.abs(m.actuator_forcerange).max(axis=1),
                              np.inf) for m in models])
    # the torque's first-order lag per step (1: none)
    follow = np.where(tlag > 0, -np.expm1(-dt / np.maximum(tlag, 1e-12)), 1.0)
    return kp, kd, lag, latency, peak, follow


def _replay(fw: Firmware, models: list[Any], control: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    kp, kd, lag, latency, peak, follow = _actuators(fw, models, dt)
    lagged = np.any(follow < 1.0)
    felt = np.any(latency > 0)
    qh = np.empty((nb2, n, nu)) if felt else None
    vh = np.empty((nb2, n, nu)) if felt else None
    out = np.zeros((nb2, nu))
    state = np.empty((nb2, n, mujoco.mj_stateSize(m0, kind)))
    delivered = np.empty((nb2, n, nu))
    sign = np.where(np.arange(nb2) < nb, 1.0, -1.0)[:, None]
    fs = _State(fw, (nb2, nu), dt, sign)
    # the torque the PD gives on the replay's own angle, without the noise it reads: what the
    # torque sensors report (the hardware's dither is its own draw, which no replay can match)
    clean = _State(replace(fw, noise=None), (nb2, nu), dt) if fw.noise else None
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
