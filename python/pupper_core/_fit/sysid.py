"""A fit through `mujoco.sysid` (``pupper_core._fit`` runs it): loading
it, the parameters' modifiers of the model, the residual and its
predictions, the weights that whiten it, and the residual its intervals
are taken from."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pupper_core._fit.replay import Firmware, rollout_fn
from pupper_core._fit.robot import Robot
from pupper_core._fit.terms import NOISE_FLOOR, FitError


def _sysid() -> Any:
    sysid: Any
    try:
        import scipy  # noqa: F401  (sysid's own imports hide a missing one)
        from mujoco import sysid
    except ImportError:
        sysid = None
    if sysid is None or not hasattr(sysid, "optimize"):
        raise FitError("pupper fit needs mujoco.sysid's dependencies: install the extra with "
                       "`make setup PUPPER_EXTRAS=fit` (or pip install 'pupper_core[fit]')")
    import logging

    logging.getLogger("absl").setLevel(logging.ERROR)
    return sysid


def _held(t: np.ndarray, target: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Targets logged slower than the physics or unevenly (time stamps as
    recorded), as a servo holds them: each from the first physics step at
    or after its instant until the next (sysid would interpolate between
    them). A delayed command is read from this history linearly between
    steps, which ramps each switch over the step before it: from the first
    step after the instant, the ramp is centred on the instant on average
    (from the nearest step, as before, it was half a step early: a fitted
    delay half a step too long). An even log at the physics rate or faster
    is sysid's to resample."""
    steps = np.diff(t)
    period = float(np.mean(steps))
    even = float(np.ptp(steps)) <= 1e-6 * period + 1e-12
    if period <= dt * (1 + 1e-9) and even:
        return t, target
    tc = np.arange(0.0, t[-1] + dt / 2, dt)
    # the target in force at each step's start: the last sent at or before it
    idx = np.searchsorted(t, tc + 1e-9 * dt, side="right") - 1
    return tc, target[np.clip(idx, 0, len(t) - 1)]


def _modifier(kind: str, members: list[int], robot: Robot, gains: dict[int, tuple[np.ndarray, np.ndarray]],
              firmware: bool = False) -> Any:
    from pupper_core._fit.replay import DELAY_SLOT, KD_SLOT, KP_SLOT, LAG_SLOT, LATENCY_SLOT

    slot = {"kp_scale": KP_SLOT, "kd_scale": KD_SLOT, "delay": DELAY_SLOT, "latency": LATENCY_SLOT, "lag": LAG_SLOT}

    def apply(spec: Any, p: Any) -> None:
        v = float(p.value[0])
        for i in members:
            act = spec.actuator(robot.actuators[i])
            if firmware and kind in slot:
                # the firmware's own gains and command delay (a torque motor's spare gain parameters)
                base = gains[id(spec)][0 if kind == "kp_scale" else 1][i] if "scale" in kind else 1.0
                act.gainprm[slot[kind]] = base * v
                continue
            if kind == "torque_limit":
                import mujoco

                act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
                act.forcerange[0], act.forcerange[1] = -v, v
            elif kind in ("armature", "damping", "frictionloss"):
                j = spec.joint(robot.joints[i])
                if kind == "damping":
                    j.damping[0] = v
                else:
                    setattr(j, kind, v)
            elif kind == "delay":
                act.delay = v
            elif kind == "kp_scale":
                kp, _ = gains[id(spec)]
                act.gainprm[0] = kp[i] * v
                act.biasprm[1] = -kp[i] * v
            elif kind == "kd_scale":
                _, kd = gains[id(spec)]
                act.biasprm[2] = -kd[i] * v
            else:
                # the firmware's own (latency): a fit that names it replays through the firmware
                raise FitError(f"{kind} is the servo firmware's: fit it through its replay (--motor)")
    return apply


def _residual_fn(sysid: Any, sequences: list[Any], enabled: list[Any], weights: np.ndarray | None,
                 firmware: Firmware | None = None) -> Any:
    through = rollout_fn(sysid, firmware) if firmware is not None else None

    def rollout(**kw: Any) -> Any:
        # mujoco.rollout's sensordata row k is the state before step k (time
        # k dt); sysid labels it one step later: put it back
        trajs = through(**kw) if through is not None else sysid.sysid_rollout(
            kw["models"], kw["datas"], kw["control_signal"], kw["initial_states"],
            kw["rollout_signal_mapping"], kw["rollout_state_mapping"], kw["ctrl_mapping"])
        dt = kw["models"][0].opt.timestep
        return [tr.replace(sensordata=sysid.TimeSeries(tr.sensordata.times - dt, tr.sensordata.data,
                                                       tr.sensordata.signal_mapping)) for tr in trajs]

    return sysid.build_residual_fn(models_sequences=sequences, custom_rollout=rollout,
                                   enabled_observations=enabled, sensor_weights=weights)


def _residual_by_log(sysid: Any, sequences: list[Any], enabled: list[list[Any]],
                     weights: list[np.ndarray | None], firmware: Firmware | None = None) -> Any:
    """The residual over logs that compare different signals (``enabled``,
    ``weights``: each log's): sysid's residual takes one set for every
    sequence, so the logs that share one are a residual of their own, and
    the pieces go back in the logs' order."""
    groups: dict[tuple[Any, ...], list[int]] = {}
    for i, on in enumerate(enabled):
        groups.setdefault(tuple(on), []).append(i)
    fns = [(idx, _residual_fn(sysid, [sequences[i] for i in idx], enabled[idx[0]], weights[idx[0]], firmware))
           for idx in groups.values()]

    def residual(x: np.ndarray, params: Any, **kw: Any) -> tuple[list[Any], list[Any], list[Any]]:
        out: list[list[Any]] = [[None] * len(sequences) for _ in range(3)]
        for idx, fn in fns:
            for part, got in zip(out, fn(x, params, **kw)):
                for i, v in zip(idx, got):
                    part[i] = v
        # sysid leaves the predictions out unless asked for them
        return out[0], [v for v in out[1] if v is not None], [v for v in out[2] if v is not None]

    return residual


#: Each log's replay: its times, the measured and the predicted signals.
Predictions = list[tuple[np.ndarray, np.ndarray, np.ndarray]]


def _predictions(residual_fn: Any, params: Any, x: np.ndarray) -> Predictions:
    """(times, measured, predicted) of every log at parameters ``x``."""
    p = params.copy()
    p.update_from_vector(x)
    _, preds, meas = residual_fn(x, p, return_pred_all=True)
    out = []
    for pr, me in zip(preds, meas):
        pt, mt = pr[0], me[0]
        pred = np.stack([np.interp(mt.times, pt.times, pt.data[:, k]) for k in range(mt.data.shape[1])], axis=1)
        out.append((mt.times, mt.data, pred))
    return out


def _rms(preds: Predictions, sensors: list[list[int]], nu: int) -> list[list[float]]:
    """Each log's RMS angle error per actuator it fits (``sensors``: each
    log's enabled sensors, the columns of its predictions, angles first)."""
    out = []
    for (_, me, pr), mine in zip(preds, sensors):
        cols = [p for p, s in enumerate(mine) if s < nu]
        out.append([float(v) for v in np.sqrt(np.mean((me[:, cols] - pr[:, cols]) ** 2, axis=0))])
    return out


def _block_err(preds: Predictions, by_log: list[list[int]], nu: int, block: int) -> np.ndarray:
    """Every log's residual of one kind of signal (angle, velocity, torque), flat."""
    own = [[c for c, s in enumerate(mine) if s // nu == block] for mine in by_log]
    return np.concatenate([(me[:, c] - pr[:, c]).ravel() for (_, me, pr), c in zip(preds, own)])


def _whitening(residual_fn: Any, opt: Any, nu: int, sensors: list[int], by_log: list[list[int]]) -> np.ndarray:
    """Weights that make each kind of signal (angle, velocity, torque)
    count by its own noise, estimated from the fit's residual (``sensors``:
    every enabled sensor, whose order the weights take; ``by_log``: each
    log's, the columns of its predictions)."""
    preds = _predictions(residual_fn, opt, opt.as_vector())
    # by position among the enabled sensors (a dict would be read by the
    # model's sensor index)
    weights = np.ones(len(sensors))
    for block in range(3):
        cols = [p for p, s in enumerate(sensors) if s // nu == block]
        if not cols:
            continue
        err = _block_err(preds, by_log, nu, block)
        sigma = max(float(np.std(err)), 1e-12)
        for p in cols:
            # sysid divides each column by its norm / sqrt(2): undo that, divide by sigma
            s = sensors[p]
            norm = np.linalg.norm(np.concatenate([me[:, mine.index(s)] for (_, me, _), mine in zip(preds, by_log)
                                                  if s in mine])) / np.sqrt(2)
            weights[p] = float(norm / sigma) if norm > 0 else 1.0
    return weights


def _interval_residuals(r_star: list[np.ndarray], preds: Predictions, weights: np.ndarray | None,
                        sensors: list[int], by_log: list[list[int]], nu: int) -> tuple[list[np.ndarray], bool]:
    """The residual the intervals' pooled variance is taken from: sysid's
    own, unless a kind of signal's RMS error lies below its NOISE_FLOOR (a
    noise-free log), where that kind counts at the floor instead
    (``weights``: by position among ``sensors``; ``by_log``: each log's
    enabled sensors)."""
    low = set()
    for block in range(3):
        cols = [p for p, s in enumerate(sensors) if s // nu == block]
        if cols:
            err = _block_err(preds, by_log, nu, block)
            if math.sqrt(float(np.mean(err ** 2))) < NOISE_FLOOR[block]:
                low.add(block)
    if not low:
        return r_star, False
    at = {s: p for p, s in enumerate(sensors)}
    # sysid divides each signal by its norm / sqrt(2) and multiplies by its weight
    total = 0.0
    for (_, me, pr), mine in zip(preds, by_log):
        for p, s in enumerate(mine):
            scale = (1.0 if weights is None else float(weights[at[s]])) * math.sqrt(2) / float(np.linalg.norm(me[:, p]))
            e2 = len(me) * NOISE_FLOOR[s // nu] ** 2 if s // nu in low else float(np.sum((me[:, p] - pr[:, p]) ** 2))
            total += scale ** 2 * e2
    size = sum(int(np.size(r)) for r in r_star)
    return [np.full(size, math.sqrt(total / size))], True


def _correlation_time(preds: Predictions, shares: dict[int, float] | None = None,
                      kinds: list[list[int]] | None = None) -> float:
    """The residual's integrated autocorrelation time (in samples, 1 for
    white noise), the mean over every log's compared signals: each sample
    of a residual that the replay cannot follow (a servo's own dither, a
    model's coarser timestep) is worth 1/tau of an independent one, so the
    Gauss-Newton intervals, which assume independent samples, are too
    narrow by sqrt(tau). Summed up to the first negative autocorrelation,
    and at most a tenth of a log.

    With ``shares`` (each kind of signal's share of the information,
    ``_information_shares``; ``kinds``: each log's compared signals' kinds), each
    kind's mean counts by its share: a kind that tells the parameters
    little does not set the widening (a firmware's torque, whose residual is
    mostly the noise of the encoder's difference velocity, white or
    anticorrelated from one sample to the next, carries well under 1 % of
    what two logs tell, yet, counted as every other signal, halved the
    angles' correlation time and narrowed every interval by 1/sqrt(2))."""
    # in the order computed (the plain mean is summed in it), and by kind
    flat: list[float] = []
    taus: dict[int, list[float]] = {}
    for li, (_, me, pr) in enumerate(preds):
        err = me - pr
        n = len(err)
        for c in range(err.shape[1]):
            e = err[:, c] - np.mean(err[:, c])
            spec = np.fft.rfft(e, 2 * n)
            ac = np.fft.irfft(spec * np.conj(spec))[: max(n // 10, 2)]
            if ac[0] <= 0:
                continue
            ac = ac / ac[0]
            stop = int(np.argmax(ac < 0)) if np.any(ac < 0) else len(ac)
            flat.append(1.0 + 2.0 * float(np.sum(ac[1:stop])))
            taus.setdefault(0 if kinds is None else kinds[li][c], []).append(flat[-1])
    if not flat:
        return 1.0
    share = {k: (shares or {}).get(k, 0.0) if kinds is not None else 0.0 for k in taus}
    total = sum(share.values())
    if not total > 0:
        return max(float(np.mean(flat)), 1.0)
    return max(sum(share[k] * float(np.mean(ts)) for k, ts in taus.items()) / total, 1.0)


def _information_shares(jac: np.ndarray, sizes: list[int], kinds: list[list[int]]) -> dict[int, float] | None:
    """Each kind of signal's share of what the logs tell the parameters:
    its rows' leverage, trace(H^-1 J_k^T J_k) over the parameters' count
    (H = J^T J: the shares sum to 1). ``sizes``: each log's residual length
    (its samples times the signals, signal fastest); ``kinds``: each log's
    signals' kinds; None where H is singular or the rows do not match."""
    if jac is None or sum(sizes) != jac.shape[0] or any(s % len(k) for s, k in zip(sizes, kinds)):
        return None
    rows = np.concatenate([np.tile(np.asarray(k), s // len(k)) for s, k in zip(sizes, kinds)])
    try:
        hinv = np.linalg.pinv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return None
    lev = {k: float(np.trace(hinv @ (jac[rows == k].T @ jac[rows == k]))) for k in sorted({k for ks in kinds for k in ks})}
    total = sum(lev.values())
    if not (math.isfinite(total) and total > 0):
        return None
    return {k: v / total for k, v in lev.items()}
