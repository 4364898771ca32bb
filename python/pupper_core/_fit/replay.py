"""`pupper fit --motor`, the fit's side of the servo firmware: --motor's
keys as fit takes them, where each rollout's servo parameters ride, and
the replay of a Jacobian's rollouts through the Rust core's firmware
(``_native.firmware_replay``: crates/pupper_core/src/sim/replay.rs, on
the firmware torque mode runs, crates/pupper_core/src/sim/firmware.rs):
the PD updated at the firmware's rate on the encoder's difference
velocity, a first-order derivative filter, the command ``delay`` ago, the
state a feedback ``latency`` late, the torque held between updates,
delivered within the torque limit (falling with speed to 0 at
``noload``) through the current loop's first-order ``lag``.

The motor is MuJoCo's: the actuators become plain torque motors; the
fitted gains, delay, latency and lag ride in each motor's unused gain
parameters (gainprm[1]: kp, [2]: kd, [3]: the command delay, [4]: the
latency, [5]: the lag), which the parameters' modifiers set, so that each
rollout of a Jacobian carries its own."""

from __future__ import annotations

import math
from dataclasses import dataclass
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
        if key in ("delay", "lag"):
            what = "command delay" if key == "delay" else "torque lag"
            raise FitError(f"--motor {key}=...: fit's {what} is its parameter '{key}' (fitted, or held at 0 when "
                           f"left out of --params): drop {key}= from --motor")
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


def _replay(fw: Firmware, models: list[Any], control: np.ndarray,
                   x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each rollout's state and sensors through the firmware ``fw``: every
    rollout of a call in one MuJoCo batch, one step call per physics step on
    all cores, the firmware between the steps the Rust core's
    (``_native.firmware_replay``, torque mode's own). With noise, the mean
    of an antithetic pair (the noise read, and its negative): the response
    to the noise itself, which no replay can match to the hardware's own
    draw, cancels to first order, and what the noise does to the friction
    (it dithers the joint loose) stays."""
    import mujoco
    import mujoco.batch

    from pupper_core._native import firmware_replay

    nb = len(models)
    sign = None
    if fw.noise:
        models, control, x0 = models * 2, np.concatenate([control, control]), np.concatenate([x0, x0])
        sign = np.where(np.arange(2 * nb) < nb, 1.0, -1.0)
    nb2, n, nu = control.shape
    m0 = models[0]
    dt = float(m0.opt.timestep)
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    whole = mujoco.mjtState.mjSTATE_INTEGRATION
    batch = mujoco.batch.Batch(m0, nb2, nthread=0)
    batch.set_models(models)
    batch.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
    rows = batch.state
    record = _components(m0, full, whole)
    rows[:, record] = x0
    jnt = m0.actuator_trnid[:, 0]
    qcol = record[1 + m0.jnt_qposadr[jnt]]
    vcol = record[1 + mujoco.mj_stateSize(m0, mujoco.mjtState.mjSTATE_QPOS) + m0.jnt_dofadr[jnt]]
    ctrl = _components(m0, mujoco.mjtState.mjSTATE_CTRL, whole)
    kp, kd, delay, latency, lag = (np.stack([m.actuator_gainprm[:, s] for m in models])
                                   for s in (KP_SLOT, KD_SLOT, DELAY_SLOT, LATENCY_SLOT, LAG_SLOT))
    peak = np.stack([np.where(m.actuator_forcelimited.astype(bool), np.abs(m.actuator_forcerange).max(axis=1),
                              np.inf) for m in models])
    # at most one update a step
    updates = min(n, int(math.ceil(n * dt * fw.rate)) + 1) if fw.rate else n
    noise = (fw.noise * np.random.default_rng(fw.seed).standard_normal((updates, nu))) if fw.noise else None
    state, delivered = firmware_replay(
        batch, rows, np.ascontiguousarray(control, dtype=float), qpos=qcol.astype(np.int64),
        qvel=vcol.astype(np.int64), ctrl=ctrl.astype(np.int64), record=record.astype(np.int64),
        kp=kp, kd=kd, delay=delay, latency=latency, lag=lag, peak=peak, timestep=dt, rate=fw.rate,
        filter=fw.filter, counts=bool(fw.counts), noload=fw.noload, noise=noise, sign=sign)
    qcol_f, vcol_f = 1 + m0.jnt_qposadr[jnt], 1 + mujoco.mj_stateSize(m0, mujoco.mjtState.mjSTATE_QPOS) + \
        m0.jnt_dofadr[jnt]
    before = np.concatenate([x0[:, None], state[:, :-1]], axis=1)
    sens = np.concatenate([before[:, :, qcol_f], before[:, :, vcol_f], delivered], axis=2)
    if nb2 > nb:
        return 0.5 * (state[:nb] + state[nb:]), 0.5 * (sens[:nb] + sens[nb:])
    return state, sens


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
