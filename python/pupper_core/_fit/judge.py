"""Judging a fit: no worse than nominal, the intervals (noise or model
error) and the spread drawn from them, what the logs cannot tell apart,
and motors of one type whose parameters disagree."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pupper_core._fit.problem import FitResult, _Problem, _Solution
from pupper_core._fit.robot import Robot
from pupper_core._fit.cover import row_segments
from pupper_core._fit.sysid import Predictions, _correlation_time, _information_shares, _interval_residuals
from pupper_core._fit.terms import CONFOUNDED, PARAMS, FitError


def _intervals(sysid: Any, pb: _Problem, residual_fn: Any, opt: Any, res: Any, weights: np.ndarray | None,
               ended: Predictions | None) -> tuple[np.ndarray, np.ndarray | None, str, float]:
    """sysid's Gauss-Newton 95 % half-widths (infinite where the logs do not
    determine a parameter), widened by the square root of the residual's
    correlation time (returned; 1 where the noise was floored), the
    correlations, and whether the residual noise behind them was floored
    at NOISE_FLOOR; ``ended``: the predictions at ``opt``. Through a
    noisy firmware (--motor noise=), each kind of signal's correlation time
    counts by its share of the information, and the spread of the fit's end
    over other draws of the replay's noise (``_draw_spread``) is added."""
    n = len(pb.labels)
    if res is None or ended is None:
        return np.full(n, math.nan), None, "none", 1.0
    r_star, _, _ = residual_fn(opt.as_vector(), opt.copy())
    by_log = [pb.sensors_of(i) for i in range(len(pb.logs))]
    r_iv, floored = _interval_residuals(r_star, ended, weights, pb.sensors, by_log, len(pb.robot.actuators))
    try:
        cov, half = sysid.calculate_intervals(r_iv, res.jac, alpha=0.05)
    except (np.linalg.LinAlgError, ValueError):
        return np.full(n, math.inf), None, "floored" if floored else "noise", 1.0
    # a noise-free log's residual is round-off, not noise: its floor stands for independent noise
    nu = len(pb.robot.actuators)
    kinds = [[s // nu for s in mine] for mine in by_log]
    # through the firmware, each kind of signal's correlation time counts by what it tells
    shares = (_information_shares(res.jac, [int(np.size(r)) for r in r_star], kinds)
              if pb.firmware is not None and len({k for ks in kinds for k in ks}) > 1 else None)
    tau = 1.0 if floored else _correlation_time(ended, shares, kinds)
    half = np.where(np.isnan(half), math.inf, half * math.sqrt(tau))
    if pb.firmware is not None and pb.firmware.noise and not floored:
        # the replay reads one draw of the noise, the fit follows it: its spread over other draws joins
        # the hardware's noise in the intervals
        spread = _draw_spread(sysid, pb, opt, res.jac, r_star, weights)
        if spread is not None:
            from scipy.special import stdtrit

            q = float(stdtrit(sum(int(np.size(r)) for r in r_star) - n, 0.975))
            half = np.sqrt(half ** 2 + q ** 2 * np.diag(spread))
            cov = cov * tau + spread
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(sd, sd)
    # a parameter the logs do not determine (a torque limit no torque reaches) correlates with nothing:
    # the others' correlations still say what the logs confound
    loose = ~np.isfinite(half) | ~np.isfinite(np.diag(cov))
    if np.any(loose) and not np.all(loose):
        corr[loose, :], corr[:, loose] = 0.0, 0.0
        corr[loose, loose] = 1.0
    source = "floored" if floored else "noise"
    if not floored:
        half, source = _model_error(pb, res.jac, r_star, ended, tau, half,
                                    _own_shifts(sysid, pb, opt, res, r_star, weights))
    return half, (corr if np.all(np.isfinite(corr)) else None), source, tau



def _model_error(pb: _Problem, jac: np.ndarray, r_star: list[np.ndarray], ended: Predictions, tau: float,
                 half: np.ndarray, shifts: np.ndarray | None = None) -> tuple[np.ndarray, str]:
    """The intervals where the residual is structure the model cannot
    follow (``_fit_intervals``): the wider of the noise's and the segments'
    spread for each parameter, and of each log's own fit (``shifts``: one
    row per log, ``_own_shifts``) where the logs disagree past the noise;
    and which one they come from."""
    from pupper_core._fit import intervals as fi

    noise, source = half, "noise"
    period = float(np.mean([np.mean(np.diff(t)) for t, _, _ in ended]))
    counts = [len(pb.sensors_of(i)) for i in range(len(pb.logs))]
    times = [t for t, _, _ in ended]
    seg = (fi.segments(times, counts[0], period, tau) if len(set(counts)) == 1
           else row_segments(fi.segments, times, counts, period, tau))
    got = fi.sandwich(jac, np.concatenate(r_star), seg) if seg is not None else None
    if got is not None and fi.model_error(noise, got[1]):
        half, source = np.where(np.isfinite(half), np.maximum(half, got[1]), half), "model error"
    if shifts is not None:
        spread = np.max(np.abs(shifts), axis=0)
        if fi.model_error(noise, spread):
            # the logs disagree past their noise: each interval holds every log's own fit
            half, source = np.where(np.isfinite(half), np.maximum(half, spread), half), "model error"
    return half, source



#: The iterations of each log's own fit (``_own_shifts``): it starts at the fit's end, a few steps away.
OWN_ITERS = 4



def _own_shifts(sysid: Any, pb: _Problem, opt: Any, res: Any, r_star: list[np.ndarray],
                weights: np.ndarray | None) -> np.ndarray | None:
    """Where each log alone takes the fit, less where the logs together
    took it, along the directions it places alone (logs, parameters); None
    with one log. Segments of one log share its gains, and a model that
    bends differently at other gains (on the real hip, a delay 1 ms longer
    and a kp scale 8 % lower at kp 7.5 than at 5) shows it only between
    logs. Each log's own fit runs from the fit's end on its rows alone
    (Levenberg–Marquardt until flat, at most OWN_ITERS iterations), and
    its shift is kept in the directions the log places alone
    (``intervals.placed``): along a valley it does not see (damping
    against kd's scale at its one kd) it wanders, and the other logs place
    that. A first-order step instead (one Gauss–Newton step on the fit's
    Jacobian) fell short of the logs' own fits, and they lay past the
    intervals it widened."""
    import dataclasses
    import io

    from pupper_core._fit import intervals as fi
    from pupper_core._fit.optimize import _optimize

    keep = fi.placed(res.jac, [int(np.size(r)) for r in r_star])
    if keep is None:
        return None
    x = opt.as_vector()
    out = []
    for i, proj in enumerate(keep):
        one = dataclasses.replace(pb, logs=[pb.logs[i]], sequences=[pb.sequences[i]], by_log=pb.by_log[i:i + 1])
        fn = one.residual_fn(sysid, weights)
        try:
            own, _ = _optimize(sysid, one, opt.copy(), fn, OWN_ITERS, io.StringIO())
        except FitError:
            # a log alone whose linear algebra fails places nothing of its own; the others' shifts stand
            out.append(np.zeros_like(x))
            continue
        out.append(proj @ (own.as_vector() - x))
    shifts = np.array(out)
    return shifts if np.all(np.isfinite(shifts)) else None



def _draw_spread(sysid: Any, pb: _Problem, opt: Any, jac: np.ndarray, r_star: list[np.ndarray],
                 weights: np.ndarray | None) -> np.ndarray | None:
    """The covariance of where the fit would end over the replay's draws of
    the encoder's noise (--motor noise=): the fit's end replayed through
    DRAWS others, each moved to its own optimum by one Gauss-Newton step
    (their spread about the fit's own, which counts as one of them). The
    pair of a draw and its negative cancels the joint's response to the
    noise to first order only: what the rest does (a draw loosens the
    friction more here than there) differs from draw to draw, and moved two
    logs' damping by 0.9 % (1 sigma) against the hardware's noise's 1.3 %."""
    from dataclasses import replace

    from pupper_core._fit.replay import DRAWS

    assert pb.firmware is not None
    x = opt.as_vector()
    try:
        hinv = np.linalg.pinv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return None
    shifts = [-(hinv @ (jac.T @ np.concatenate(r_star)))]
    for seed in range(pb.firmware.seed + 1, pb.firmware.seed + 1 + DRAWS):
        fn = pb.residual_fn(sysid, weights, replace(pb.firmware, seed=seed))
        r, _, _ = fn(x, opt.copy())
        r = np.concatenate(r)
        if r.shape[0] != jac.shape[0] or not np.all(np.isfinite(r)):
            return None
        shifts.append(-(hinv @ (jac.T @ r)))
    spread = np.atleast_2d(np.cov(np.stack(shifts), rowvar=False))
    return spread if np.all(np.isfinite(spread)) else None



def _judge(pb: _Problem, sol: _Solution, table: list[dict[str, Any]]) -> list[str]:
    """What the user must know of each parameter (``table``: fit.csv's rows,
    its intervals): on a bound, undetermined, an interval past a physical
    bound (every parameter is >= 0), a delay under one timestep, confounded
    pairs; and logs the fit made worse."""
    out: list[str] = []
    lo_b, hi_b = pb.pdict.get_bounds()
    for i, (name, kind, _, _) in enumerate(pb.labels):
        x, h, unit = float(sol.x[i]), float(sol.half[i]), PARAMS[kind][0]
        low, high = table[i]["low95"], table[i]["high95"]
        u = f" {unit}" if unit else ""
        span = float(hi_b[i] - lo_b[i])
        bound = next(((side, b) for side, b in (("lower", float(lo_b[i])), ("upper", float(hi_b[i])))
                      if abs(x - b) <= 1e-6 * span), None)
        if bound is not None:
            # a Gauss-Newton interval assumes a minimum inside the bounds
            out.append(f"{name} ends on its {bound[0]} bound ({bound[1]:g}{u}): its interval is not meaningful; "
                       "the logs ask for a value the fit does not allow, or show none")
        if kind == "delay" and 0 < x < pb.robot.timestep * (1 - 1e-9):
            out.append(f"{name} ends at {x:.3g} s, under one timestep ({pb.robot.timestep:g} s): MuJoCo applies "
                       "any delay up to a timestep as a whole step, so the logs cannot place it there; read it "
                       f"as 0 or {pb.robot.timestep:g} s")
        if math.isinf(h) and kind == "torque_limit":
            # a limit no torque reaches leaves the replay as it is: the logs bound it from below only
            nom = float(table[i]["nominal"])
            if abs(x - nom) <= 1e-9 * nom:
                said = f"the logs never reach it ({x:.4g} N·m, the model's): they show no limit on the torque they ask"
            else:
                said = (f"the logs ask more torque than the model's {nom:g} N·m and show no limit on it: the motor "
                        f"delivers at least {x:.4g} N·m")
            out.append(f"{name}: {said}; its 95 % interval is infinite (a log that saturates the motor, at a "
                       "higher kp or amplitude, places it)")
        elif math.isinf(h):
            out.append(f"{name}: the logs do not determine it (its 95 % interval is infinite): leave it out "
                       "of --params, or give logs that excite it")
        elif bound is None and math.isfinite(h) and low < 0:
            out.append(f"{name}'s 95 % interval [{low:.4g}, {high:.4g}]{u} reaches below 0, which it cannot "
                       "be: the logs show it poorly or it is near 0; read its upper end as a bound")
    kinds = {label[1]: i for i, label in enumerate(pb.labels)}
    if "latency" in kinds and "delay" in kinds and (math.isinf(float(sol.half[kinds["latency"]]))
                                                   or math.isnan(float(sol.half[kinds["latency"]]))):
        out.append("latency and delay: the logs cannot tell the feedback latency (inside the loop: it changes "
                   "the resonance) from the command delay (outside it: a pure lag); add a log at another kp (another kd "
                   "does not separate them: at one kp a latency reads as less damping), or fit one of them")
    if sol.source == "model error":
        rms = float(np.mean([np.mean(a) for a in sol.after])) * 1e3
        out.append(f"the residual ({rms:.3g} mrad RMS) is structure the model cannot follow, not noise: each "
                   "interval is the widest of the noise's, the spread over the logs' segments (a block "
                   "sandwich, what leaving segments in or out would move) and, with several logs, each log's "
                   "own fit; it says how far the model's error lets the logs place each value, not a sensor's "
                   "precision" + ("" if {"lag", "latency"} & set(kinds) else
                                  "; a servo's torque lag is a common cause on real motors: try --params "
                                  + ",".join(dict.fromkeys([*kinds, "lag"]))))
    out += _confounded(pb, sol)
    for lg, rms0, rms1 in zip(pb.logs, sol.before, sol.after):
        # by more than 1 % and a micro-radian: not round-off
        if np.mean(rms1) > 1.01 * np.mean(rms0) + 1e-6:
            out.append(f"{lg.path.name}: the RMS angle error rose ({np.mean(rms0) * 1e3:.3f} -> "
                       f"{np.mean(rms1) * 1e3:.3f} mrad): the fitted model explains it worse than the nominal one; "
                       "check the log (an angle offset, the gains in its header)")
    return out



#: A correlation past which the feedback latency and the command delay are said to be one to the logs.
APART = 0.9



def _confounded(pb: _Problem, sol: _Solution) -> list[str]:
    out: list[str] = []
    if sol.corr is None:
        return out
    for i, (a_name, a_kind, a_mem, _) in enumerate(pb.labels):
        for j, (b_name, b_kind, b_mem, _) in enumerate(pb.labels):
            c = float(sol.corr[i, j])
            apart = a_mem == b_mem and {a_kind, b_kind} == {"delay", "latency"}
            # the latency and the delay are said at APART: past 0.95 only, one log's pair (0.94 on the
            # stand-in at one kp, where the latency landed at 2.5 ms for 6) went unsaid
            if i >= j or abs(c) <= (APART if apart else 0.95):
                continue
            if apart:
                out.append(f"{a_name} and {b_name} are confounded (correlation {c:+.2f}): the logs cannot tell "
                           "the feedback latency (inside the loop: it changes the resonance) from the command "
                           "delay (outside it: a pure lag); add a log at another kp (another kd does not separate "
                           "them: at one kp a latency reads as less damping), or fit one of them")
            elif a_mem == b_mem and {a_kind, b_kind} == {"damping", "kd_scale"}:
                out.append(f"{a_name} and {b_name} are confounded (correlation {c:+.2f}): the logs "
                           "show only their sum; add a log at another kd (pupper excite --kd) or a torque column")
            elif abs(c) > CONFOUNDED:
                out.append(f"{a_name} and {b_name} are confounded (correlation {c:+.3f}): the logs cannot tell "
                           "them apart; leave one out of --params, or add logs that separate them")
    return out



#: The parameters of the motor itself, which motors of one type share (the link's own, armature and
#: damping, stay per joint: they carry the link's inertia and losses).
MOTOR_KINDS = ("kp_scale", "kd_scale", "delay", "lag", "latency", "frictionloss", "torque_limit")



#: What each motor parameter's disagreement puts in doubt: the part of the model it stands for.
_SUSPECT = {
    "gain": "the motor model's gain structure (a gain scale stands in for what differs from joint to joint "
            "and the model leaves out: the link's inertia or load, a transmission, the torque limit at speed)",
    "timing": "the motor model's timing structure (a command delay and a first-order torque lag: the logs' "
              "time stamps or loop rate differ, or the servo's lag is not first-order)",
    "friction": "the friction model (Coulomb friction loss alone: the joints' own friction, seals or cables, "
                "differs, or friction varies with speed, viscous or Stribeck)",
}



_PART = {"kp_scale": "gain", "kd_scale": "gain", "delay": "timing", "lag": "timing", "latency": "timing",
         "frictionloss": "friction", "torque_limit": "gain"}



def fit_entries(res: FitResult, label: str = "") -> list[tuple[str, str, float, float, float]]:
    """A fit's motor parameters as (kind, motors, value, low, high): the
    motors are the logged actuators a value stands for (fit.csv lists every
    actuator it goes to), ``label`` said after them (a fit's run)."""
    out = []
    for r in res.table:
        if r["kind"] not in MOTOR_KINDS:
            continue
        motors = [a for a in r["actuators"].split() if a in res.actuators]
        _, lo, hi = PARAMS[r["kind"]]
        # a value on its bound has no meaningful interval (the fit warns of it): nothing to compare
        on_bound = min(abs(r["fitted"] - lo), abs(r["fitted"] - max(hi, 4 * r["nominal"]))) <= 1e-6 * (hi - lo)
        if motors and not on_bound:
            out.append((r["kind"], " ".join(motors) + (f" ({label})" if label else ""), float(r["fitted"]),
                        float(r["low95"]), float(r["high95"])))
    return out



def disagreements(entries: Sequence[tuple[str, str, float, float, float]],
                  type_of: Mapping[str, float]) -> list[str]:
    """Warnings for motors of one type (``type_of``: an actuator's torque
    limit, its type) whose motor parameter comes out with disjoint 95 %
    intervals (``entries``: ``fit_entries``' rows, of one fit per joint or
    of several fits): each names the parameter, the motors, their values
    and intervals, and the part of the model it suspects: motors of one
    type are one motor, so a parameter that differs while the others agree
    points at the model's structure for that part, not at the motors. An
    interval not meaningful (NaN) or infinite is never disjoint."""
    def kind_of(motors: str) -> float | None:
        types = {type_of.get(a) for a in motors.split(" (")[0].split()}
        return types.pop() if len(types) == 1 else None

    groups: dict[tuple[str, float], list[tuple[str, float, float, float]]] = {}
    for kind, motors, x, lo, hi in entries:
        t = kind_of(motors)
        if t is not None and math.isfinite(lo) and math.isfinite(hi):
            groups.setdefault((kind, t), []).append((motors, x, lo, hi))
    split: dict[tuple[str, float], list[tuple[int, int]]] = {}
    for key, rows in groups.items():
        pairs = [(i, j) for i in range(len(rows)) for j in range(i + 1, len(rows))
                 if rows[i][3] < rows[j][2] or rows[j][3] < rows[i][2]]
        if pairs:
            split[key] = pairs
    out = []
    for (kind, t), pairs in split.items():
        rows = groups[(kind, t)]
        apart = sorted({k for p in pairs for k in p})
        said = ", ".join(f"{rows[k][0]} {rows[k][1]:.4g} [{rows[k][2]:.4g}, {rows[k][3]:.4g}]" for k in apart)
        agree = sorted(k2 for (k2, t2), rs in groups.items() if t2 == t and len(rs) > 1 and (k2, t2) not in split)
        limit = f"torque limit {t:g} N·m" if math.isfinite(t) else "no torque limit"
        unit = PARAMS[kind][0]
        text = (f"{kind} disagrees between motors of one type ({limit}): {said}{' ' + unit if unit else ''}, "
                "intervals disjoint")
        if agree:
            text += f", while {', '.join(agree)} agree{'s' if len(agree) == 1 else ''}"
        others = {k2 for k2, t2 in split if t2 == t} - {kind}
        if others and not agree:
            text += (f"; {', '.join(sorted(others))} disagree too: the motors themselves may differ (a worn "
                     "or another motor), or the joints' model (link inertia, load) is wrong")
        else:
            also = f" ({', '.join(sorted(others))} disagree{'s' if len(others) == 1 else ''} too)" if others else ""
            text += f": suspect {_SUSPECT[_PART[kind]]}{also}, not the motors"
        out.append(text)
    return out



def motor_types(robot: Robot) -> dict[str, float]:
    """Each actuator's type: its torque limit (the model says no more of a motor)."""
    return {a: float(robot.limits[k]) for k, a in enumerate(robot.actuators)}
