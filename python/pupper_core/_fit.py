"""`pupper fit` and `pupper excite`: the model calibrated to a robot's joint
logs with MuJoCo's system-identification toolbox (`mujoco.sysid`).

`excite` writes a trajectory to play on the hardware (per joint group a
multisine or chirp around the rest pose, inside the joint ranges and under
velocity and torque limits, with holds between) and the nominal model's
response to it, in the joint-log format (`pupper_core._joint_log`).

`fit` replays each log's targets, at the log's gains, through the robot
hung in the air (the free joint removed, contacts off), and fits joint
armature, damping and friction loss, the servo's kp and kd scales and its
command delay to the logged angles (and torques, where logged) by
`mujoco.sysid`'s bounded Levenberg–Marquardt, every rollout of a Jacobian
in one batch on all cores. Intervals are sysid's Gauss–Newton 95 % ones.

Outputs (a run directory): ``fit.csv``, ``calibrated.xml`` (the model with
the fitted values, written through `MjSpec`; every command loads it with
``--model``), ``residuals.csv``, ``manifest.json`` and, with ``plot``,
``plots/fit_<log>.png`` (measured against simulated angle per joint,
before and after).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._joint_log import JointLog, LogError, read_log, write_log

__all__ = ["fit", "excite", "FitResult", "FitError", "PARAMS"]

#: Each fittable quantity: unit, lower bound, upper bound (None: from the nominal).
PARAMS: dict[str, tuple[str, float, float]] = {
    "armature": ("kg·m²", 0.0, 0.05),
    "damping": ("N·m·s/rad", 0.0, 1.0),
    "frictionloss": ("N·m", 0.0, 1.0),
    "kp_scale": ("", 0.2, 5.0),
    "kd_scale": ("", 0.2, 5.0),
    "delay": ("s", 0.0, 0.05),
}
DEFAULT_PARAMS = ("armature", "damping", "frictionloss", "kp_scale", "kd_scale", "delay")
GROUPS = ("haa", "hfe", "kfe")
PER = ("all", "group", "joint")
#: The custom numeric a calibrated model keeps a gain scale in, per actuator.
SCALE_NUMERIC = "pupper:{kind}:{actuator}"


class FitError(ValueError):
    """Bad input to `fit` or `excite`: one line naming the problem and the fix."""


def _sysid() -> Any:
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


# ---------------------------------------------------------------- the robot


def _model_file(model: str | os.PathLike[str]) -> Path:
    p = Path(model)
    if p.is_file():
        return p.resolve()
    builtin = Path(__file__).parent / "models" / str(model) / "scene.xml"
    if builtin.is_file():
        return builtin
    raise FitError(f"model '{model}' is neither an MJCF file nor a built-in model with a file "
                   "(pupper_v3): give --model PATH or pupper_v3")


@dataclass
class Robot:
    """What the fit needs of a model: its actuators, their joints, groups,
    ranges, torque limits and nominal joint parameters."""

    file: Path
    actuators: list[str]
    joints: list[str]
    groups: list[str]
    ranges: dict[str, tuple[float, float] | None]
    limits: np.ndarray
    own_kp: np.ndarray
    own_kd: np.ndarray
    armature: np.ndarray
    damping: np.ndarray
    frictionloss: np.ndarray
    rest: np.ndarray
    timestep: float

    def members(self, per: str) -> list[tuple[str, list[int]]]:
        """The parameter sets: (suffix, actuator indices)."""
        if per == "all":
            return [("", list(range(len(self.actuators))))]
        if per == "joint":
            return [(f".{a}", [i]) for i, a in enumerate(self.actuators)]
        out = [(f".{g}", [i for i, x in enumerate(self.groups) if x == g]) for g in GROUPS]
        return [(s, m) for s, m in out if m]


def load_robot(model: str | os.PathLike[str]) -> Robot:
    import mujoco

    import pupper_core as pc

    path = _model_file(model)
    try:
        m = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as e:
        raise FitError(f"model '{path}' does not compile ({str(e).splitlines()[0]}): fix the MJCF") from None
    info = pc.info(str(path))
    group_of: dict[int, str] = {}
    for leg in info["legs"]:
        for k, j in enumerate(leg["joints"]):
            group_of[j] = GROUPS[min(k, 2)]
    acts, joints, groups, ranges, limits = [], [], [], {}, []
    own_kp, own_kd, arm, damp, fric, rest = [], [], [], [], [], []
    key = next((k for k in range(m.nkey) if mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_KEY, k) == "home"), None)
    for a, ai in enumerate(info["actuators"]):
        j = ai["joint"]
        if j is None:
            raise FitError(f"actuator '{ai['name']}' drives no joint: fit needs joint actuators")
        jid = int(m.actuator_trnid[a, 0])
        acts.append(ai["name"])
        joints.append(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, jid))
        groups.append(group_of.get(j, "joint"))
        lim = m.jnt_range[jid] if m.jnt_limited[jid] else None
        ranges[ai["name"]] = (float(lim[0]), float(lim[1])) if lim is not None else None
        fr = ai["forcerange"]
        limits.append(max(abs(fr[0]), abs(fr[1])) if fr else math.inf)
        g, b = ai["gainprm"], ai["biasprm"]
        own_kp.append(g[0] if b[1] == -g[0] else math.nan)
        own_kd.append(-b[2] if b[1] == -g[0] else math.nan)
        dof = int(m.jnt_dofadr[jid])
        arm.append(float(m.dof_armature[dof]))
        damp.append(float(m.dof_damping[dof]))
        fric.append(float(m.dof_frictionloss[dof]))
        q = float(m.key_ctrl[key, a]) if key is not None and m.nu else float(m.qpos0[m.jnt_qposadr[jid]])
        if lim is not None:
            q = min(max(q, lim[0] + 0.1), lim[1] - 0.1)
        rest.append(q)
    return Robot(path, acts, joints, groups, ranges, np.array(limits), np.array(own_kp),
                 np.array(own_kd), np.array(arm), np.array(damp), np.array(fric), np.array(rest),
                 float(m.opt.timestep))


def _history_samples(robot: Robot) -> int:
    return int(math.ceil(PARAMS["delay"][2] / robot.timestep)) + 3


def suspended_spec(robot: Robot, kp: np.ndarray, kd: np.ndarray) -> Any:
    """The robot hung in the air at the given gains, sensing each actuated
    joint's angle, velocity and actuator force (sensors in that order)."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(robot.file))
    for j in list(spec.joints):
        if j.type == mujoco.mjtJoint.mjJNT_FREE:
            spec.delete(j)
    for k in list(spec.keys):
        spec.delete(k)
    for s in list(spec.sensors):
        spec.delete(s)
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    n = _history_samples(robot)
    for i, name in enumerate(robot.actuators):
        act = spec.actuator(name)
        act.gainprm[0] = kp[i]
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.biasprm[0] = 0.0
        act.biasprm[1] = -kp[i]
        act.biasprm[2] = -kd[i]
        act.nsample = n
        act.interp = 1
    for kind, obj in ((mujoco.mjtSensor.mjSENS_JOINTPOS, "joint"), (mujoco.mjtSensor.mjSENS_JOINTVEL, "joint"),
                      (mujoco.mjtSensor.mjSENS_ACTUATORFRC, "actuator")):
        for i, name in enumerate(robot.actuators):
            target = robot.joints[i] if obj == "joint" else name
            spec.add_sensor(name=f"pupper_{kind.name}_{name}", type=kind,
                            objtype=mujoco.mjtObj.mjOBJ_JOINT if obj == "joint" else mujoco.mjtObj.mjOBJ_ACTUATOR,
                            objname=target)
    return spec


def initial_state(model: Any, robot: Robot, q0: np.ndarray, qd0: np.ndarray, target0: np.ndarray) -> np.ndarray:
    """The full physics state at a log's start: its angles and velocities,
    and a command history that has held the first target."""
    import mujoco

    d = mujoco.MjData(model)
    for i, j in enumerate(robot.joints):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        d.qpos[model.jnt_qposadr[jid]] = q0[i]
        d.qvel[model.jnt_dofadr[jid]] = qd0[i]
    d.ctrl[:] = target0
    for a in range(model.nu):
        n = int(model.actuator_history[a, 0])
        if n:
            mujoco.mj_initCtrlHistory(model, d, a, None, np.full((n, 1), float(target0[a])))
    state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, d, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return state


def simulate(spec: Any, robot: Robot, times: np.ndarray, targets: np.ndarray,
             q0: np.ndarray | None = None, settle: float = 1.0) -> np.ndarray:
    """Angles, velocities and torques (samples, 3 nu) of the targets played
    through `spec`, after ``settle`` seconds held at the first target
    (started there, or at ``q0``)."""
    import mujoco
    from mujoco import rollout

    m = spec.compile()
    dt = float(np.median(np.diff(times)))
    if abs(dt - m.opt.timestep) > 1e-9:
        m.opt.timestep = dt
    x0 = initial_state(m, robot, targets[0] if q0 is None else q0, np.zeros(m.nu), targets[0])
    if settle > 0:
        # the robot has rested at the first target before the log starts
        hold = np.tile(targets[0], (round(settle / dt), 1))
        state, _ = rollout.rollout(m, mujoco.MjData(m), x0, hold)
        x0 = np.asarray(state[0, -1])
    _, sens = rollout.rollout(m, mujoco.MjData(m), x0, targets)
    return np.asarray(sens[0])


# ------------------------------------------------------------------- excite


def _multisine(t: np.ndarray, band: tuple[float, float], count: int, rng: np.random.Generator) -> np.ndarray:
    f = np.geomspace(band[0], band[1], count)
    # Schroeder-like phases keep the crest factor low; a random offset per joint
    k = np.arange(1, count + 1)
    phase = -np.pi * k * (k - 1) / count + rng.uniform(0, 2 * np.pi)
    s = np.sin(2 * np.pi * f[:, None] * t[None, :] + phase[:, None]).sum(0)
    return s / np.max(np.abs(s))


def _chirp(t: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    f0, f1 = band
    span = t[-1] if t[-1] > 0 else 1.0
    r = (f1 / f0) ** (1 / span)
    return np.sin(2 * np.pi * f0 * (r ** t - 1) / math.log(r))


def excite(model: str | os.PathLike[str] = "pupper_v3", *, out: str | os.PathLike[str] = "excite.csv",
           kp: float | None = None, kd: float | None = None, seconds: float = 8.0, hold: float = 1.0,
           amplitude: float = 0.3, signal: str = "multisine", band: Sequence[float] = (0.3, 6.0),
           max_velocity: float = 8.0, seed: int = 0, force: bool = False) -> Path:
    """Writes an excitation to play on the robot and the nominal model's
    response to it, in the joint-log format; returns the file's path."""
    robot = load_robot(model)
    out = Path(out)
    if out.exists() and not force:
        raise FitError(f"{out} exists: give another --out, or --force to overwrite it")
    if signal not in ("multisine", "chirp"):
        raise FitError(f"--signal {signal} is unknown: use multisine or chirp")
    lo, hi = (float(b) for b in band)
    if not (0 < lo < hi < 0.5 / robot.timestep / 4):
        raise FitError(f"--band {lo:g},{hi:g} Hz is not 0 < F0 < F1 below a quarter of the "
                       f"Nyquist rate ({0.125 / robot.timestep:g} Hz): give e.g. 0.3,6")
    for name, v in (("seconds", seconds), ("amplitude", amplitude), ("max-velocity", max_velocity)):
        if not (math.isfinite(v) and v > 0):
            raise FitError(f"--{name} {v} must be > 0")
    if not (math.isfinite(hold) and hold >= 0):
        raise FitError(f"--hold {hold} must be >= 0")
    gains_kp = np.full(len(robot.actuators), kp) if kp is not None else robot.own_kp
    gains_kd = np.full(len(robot.actuators), kd) if kd is not None else robot.own_kd
    if np.isnan(gains_kp).any() or np.isnan(gains_kd).any() or (gains_kp < 0).any() or (gains_kd < 0).any():
        raise FitError("the model's actuators have no PD gains of their own: give --kp and --kd")
    dt = robot.timestep
    rng = np.random.default_rng(seed)
    groups = [g for g in GROUPS if g in robot.groups] or ["joint"]
    n_seg = int(round(seconds / dt))
    n_hold = int(round(hold / dt))
    total = n_hold + len(groups) * (n_seg + n_hold)
    times = np.arange(total + 1) * dt
    targets = np.tile(robot.rest, (total + 1, 1))
    ts = np.arange(n_seg) * dt
    taper = np.minimum(1.0, np.minimum(ts, ts[-1] - ts) / 0.5) if n_seg > 1 else np.ones(1)
    taper = 0.5 - 0.5 * np.cos(np.pi * taper)
    for gi, g in enumerate(groups):
        start = n_hold + gi * (n_seg + n_hold)
        for a in (i for i, x in enumerate(robot.groups) if x == g or g == "joint"):
            s = (_multisine(ts, (lo, hi), 8, rng) if signal == "multisine" else _chirp(ts, (lo, hi))) * taper
            speed = np.max(np.abs(np.diff(s))) / dt
            amp = min(amplitude, max_velocity / max(speed, 1e-9))
            rng_a = robot.ranges[robot.actuators[a]]
            if rng_a is not None:
                amp = min(amp, robot.rest[a] - rng_a[0] - 0.05, rng_a[1] - robot.rest[a] - 0.05)
            if gains_kp[a] > 0 and math.isfinite(robot.limits[a]):
                # the PD's stiffness alone may ask 80 % of the motor's torque
                amp = min(amp, 0.8 * robot.limits[a] / gains_kp[a])
            targets[start:start + n_seg, a] = robot.rest[a] + max(amp, 0.0) * s
    spec = suspended_spec(robot, gains_kp, gains_kd)
    sens = simulate(spec, robot, times, targets)
    nu = len(robot.actuators)
    write_log(out, times, robot.actuators, target=targets, q=sens[:, :nu], qd=sens[:, nu:2 * nu],
              tau=sens[:, 2 * nu:], kp=gains_kp, kd=gains_kd,
              note=f"pupper excite {signal} {lo:g}-{hi:g} Hz; q, qd, tau: the nominal model's response")
    return out


# ---------------------------------------------------------------------- fit


@dataclass
class FitResult:
    """What `fit` found: ``table`` is fit.csv's rows; ``rms_before`` and
    ``rms_after`` the RMS angle error (rad) of each log, per actuator."""

    table: list[dict[str, Any]]
    rms_before: dict[str, list[float]]
    rms_after: dict[str, list[float]]
    out: Path | None
    seconds: float
    warnings: list[str] = field(default_factory=list)
    actuators: list[str] = field(default_factory=list)

    def value(self, name: str) -> float:
        return next(float(r["fitted"]) for r in self.table if r["parameter"] == name)

    def interval(self, name: str) -> tuple[float, float]:
        r = next(r for r in self.table if r["parameter"] == name)
        return float(r["low95"]), float(r["high95"])


def _parse_params(params: str | Sequence[str]) -> list[str]:
    names = [p.strip() for p in (params.split(",") if isinstance(params, str) else params) if p.strip()]
    if not names:
        raise FitError("--params is empty: name some of " + ", ".join(PARAMS))
    for n in names:
        if n not in PARAMS:
            raise FitError(f"--params names '{n}', which fit does not know: use any of {', '.join(PARAMS)}")
    if len(set(names)) != len(names):
        raise FitError("--params names a parameter twice: keep one")
    return names


def fit(logs: Sequence[str | os.PathLike[str]], *, model: str | os.PathLike[str] = "pupper_v3",
        params: str | Sequence[str] = DEFAULT_PARAMS, per: str = "all", out: str | os.PathLike[str] | None = None,
        force: bool = False, max_iters: int = 50, plot: bool = False, progress: bool = True) -> FitResult:
    """Fits ``params`` (per ``all`` actuators, joint ``group`` or ``joint``)
    to the joint ``logs`` and, with ``out``, writes the run directory."""
    names = _parse_params(params)
    if per not in PER:
        raise FitError(f"--per {per} is unknown: use all, group or joint")
    if not logs:
        raise FitError("no log given: pupper fit LOG.csv [LOG.csv ...] (pupper excite writes one)")
    if max_iters < 1:
        raise FitError("--max-iters must be >= 1")
    out_dir = Path(out) if out is not None else None
    if out_dir is not None and out_dir.exists() and any(out_dir.iterdir()) and not force:
        raise FitError(f"{out_dir} exists and is not empty: give another --out, or --force")
    robot = load_robot(model)
    try:
        read = [read_log(p, robot.ranges) for p in logs]
    except LogError as e:
        raise FitError(str(e)) from None
    for lg in read:
        missing = [a for a in robot.actuators if a not in lg.actuators]
        if missing:
            raise FitError(f"{lg.path}: column '{missing[0]}.target' is missing: a log must cover "
                           f"every actuator of the model ({len(robot.actuators)})")
        if lg.base != "suspended":
            raise FitError(f"{lg.path}: '# base: {lg.base}': fit replays logs of the robot hung in "
                           "the air (base: suspended); standing logs are not supported yet")
        if lg.duration <= PARAMS["delay"][2] * 4:
            raise FitError(f"{lg.path}: the log spans {lg.duration:g} s, too short for the delay "
                           f"range (0 to {PARAMS['delay'][2]:g} s): log at least a few seconds")
        dts = np.diff(lg.times)
        if np.max(np.abs(dts - dts.mean())) > 1e-6 * max(dts.mean(), 1e-9) + 1e-9:
            raise FitError(f"{lg.path}: samples are not evenly spaced in time: resample the log "
                           "to a fixed rate")
    sysid = _sysid()
    import mujoco

    started = time.perf_counter()
    order = [lg.actuators.index(a) for a in robot.actuators]
    # one spec per gain setting: its actuators run at the logged gains
    specs: dict[tuple[bytes, bytes], Any] = {}
    gains: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    sequences = []
    nu = len(robot.actuators)
    has_tau = all(lg.tau is not None for lg in read)
    has_qd = all(lg.qd is not None for lg in read)
    sensors = [*range(nu)] + ([*range(nu, 2 * nu)] if has_qd else []) + ([*range(2 * nu, 3 * nu)] if has_tau else [])
    for li, lg in enumerate(read):
        kp, kd = lg.kp[order], lg.kd[order]
        key = (kp.tobytes(), kd.tobytes())
        if key not in specs:
            spec = suspended_spec(robot, kp, kd)
            specs[key] = spec
            gains[id(spec)] = (kp, kd)
        spec = specs[key]
        # the model steps at its own timestep; sysid resamples the logged
        # targets to it and the predictions to the log's times
        m = spec.compile()
        t = lg.times - lg.times[0]
        target = lg.target[:, order]
        q = lg.q[:, order]
        cols = [q, lg.qd[:, order] if has_qd else np.zeros_like(q), lg.tau[:, order] if has_tau else np.zeros_like(q)]
        y = np.hstack(cols)
        # the start: where the robot rests when the log begins on a hold
        # (the mean of its first samples, less noise than one)
        held = int(np.argmax(np.any(target != target[0], axis=1))) or len(target)
        n0 = max(1, min(held, round(0.01 / float(np.mean(np.diff(t))))))
        q0 = q[:n0].mean(axis=0) if held >= n0 and not has_qd else q[0]
        qd0 = cols[1][0] if has_qd else np.zeros(nu)
        x0 = initial_state(m, robot, q0, qd0, target[0])
        control = sysid.TimeSeries.from_control_names(*_held(t, target, m.opt.timestep), m)
        measured = sysid.TimeSeries.from_names(t, y, m)
        sequences.append(sysid.ModelSequences(f"log{li}", spec, lg.path.stem, x0, control, measured))

    pdict = sysid.ParameterDict()
    nominal = {"armature": robot.armature, "damping": robot.damping, "frictionloss": robot.frictionloss}
    labels: list[tuple[str, str, list[int], float]] = []
    for kind in names:
        for suffix, members in robot.members(per):
            if kind in nominal:
                values = nominal[kind][members]
                nom = float(values[0]) if np.all(values == values[0]) else float(np.mean(values))
            else:
                nom = 1.0 if "scale" in kind else 0.0
            _, lo, hi = PARAMS[kind]
            modifier = _modifier(kind, members, robot, gains)
            pdict.add(sysid.Parameter(kind + suffix, nom, lo, max(hi, 4 * nom), modifier=modifier))
            labels.append((kind + suffix, kind, members, nom))
    pdict.move_off_bounds()
    enabled = [(s.name, sysid.SignalType.MjSensor) for s in sequences[0].spec.sensors
               if [x.name for x in sequences[0].spec.sensors].index(s.name) in sensors]
    weights = None
    residual_fn = _residual_fn(sysid, sequences, enabled, weights)
    x_nominal = pdict.as_vector().copy()
    before = _rms(residual_fn, pdict, x_nominal, nu)
    sink = io.StringIO()
    opt, res = sysid.optimize(pdict, residual_fn, optimizer="mujoco", verbose=False,
                              max_iters=max_iters, x_scale="jac", output=sink)
    if has_tau or has_qd:
        # whiten: each kind of signal by its own noise, so the pooled
        # variance of the intervals means something
        weights = _whitening(residual_fn, opt, nu, sensors)
        residual_fn = _residual_fn(sysid, sequences, enabled, weights)
        opt, res = sysid.optimize(opt, residual_fn, optimizer="mujoco", verbose=False,
                                  max_iters=max_iters, x_scale="jac", output=sink)
    r_star, _, _ = residual_fn(opt.as_vector(), opt.copy())
    _, half = sysid.calculate_intervals(r_star, res.jac, alpha=0.05)
    after = _rms(residual_fn, opt, opt.as_vector(), nu)
    x = opt.as_vector()
    warnings: list[str] = []
    cov, _ = sysid.calculate_intervals(r_star, res.jac, alpha=0.05)
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(sd, sd)
    for i, (a_name, a_kind, a_mem, _) in enumerate(labels):
        for j, (b_name, b_kind, b_mem, _) in enumerate(labels):
            if i < j and a_mem == b_mem and {a_kind, b_kind} == {"damping", "kd_scale"} and abs(corr[i, j]) > 0.95:
                warnings.append(
                    f"{a_name} and {b_name} are confounded (correlation {corr[i, j]:+.2f}): the logs "
                    "show only their sum; add a log at another kd (pupper excite --kd) or a torque column")
    table = []
    for i, (name, kind, members, nom) in enumerate(labels):
        unit = PARAMS[kind][0]
        table.append({"parameter": name, "kind": kind, "actuators": " ".join(robot.actuators[k] for k in members),
                      "nominal": nom, "fitted": float(x[i]), "low95": float(x[i] - half[i]),
                      "high95": float(x[i] + half[i]), "unit": unit})
    seconds = time.perf_counter() - started
    result = FitResult(table, {lg.path.name: v for lg, v in zip(read, before)},
                       {lg.path.name: v for lg, v in zip(read, after)}, out_dir, seconds, warnings,
                       list(robot.actuators))
    if out_dir is not None:
        _write(out_dir, result, robot, read, labels, x, model, names, per, force)
        if plot:
            _plot(out_dir, robot, read, sequences, residual_fn, pdict, x_nominal, opt)
        from pupper_core import _report

        _report.report(out_dir)
    return result


def _held(t: np.ndarray, target: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Targets logged slower than the physics, as a servo holds them: each
    one until the next (sysid would interpolate between them)."""
    period = float(np.mean(np.diff(t)))
    if period <= dt * (1 + 1e-9):
        return t, target
    tc = np.arange(0.0, t[-1] + dt / 2, dt)
    idx = np.searchsorted(t, tc + 1e-9 * dt, side="right") - 1
    return tc, target[np.clip(idx, 0, len(t) - 1)]


def _modifier(kind: str, members: list[int], robot: Robot, gains: dict[int, tuple[np.ndarray, np.ndarray]]) -> Any:
    def apply(spec: Any, p: Any) -> None:
        v = float(p.value[0])
        for i in members:
            if kind in ("armature", "damping", "frictionloss"):
                j = spec.joint(robot.joints[i])
                if kind == "damping":
                    j.damping[0] = v
                else:
                    setattr(j, kind, v)
            elif kind == "delay":
                spec.actuator(robot.actuators[i]).delay = v
            else:
                kp, kd = gains[id(spec)]
                act = spec.actuator(robot.actuators[i])
                if kind == "kp_scale":
                    act.gainprm[0] = kp[i] * v
                    act.biasprm[1] = -kp[i] * v
                else:
                    act.biasprm[2] = -kd[i] * v
    return apply


def _residual_fn(sysid: Any, sequences: list[Any], enabled: list[Any], weights: np.ndarray | None) -> Any:
    def rollout(**kw: Any) -> Any:
        # mujoco.rollout's sensordata row k is the state before step k (time
        # k dt); sysid labels it one step later: put it back
        trajs = sysid.sysid_rollout(kw["models"], kw["datas"], kw["control_signal"], kw["initial_states"],
                                    kw["rollout_signal_mapping"], kw["rollout_state_mapping"], kw["ctrl_mapping"])
        dt = kw["models"][0].opt.timestep
        return [tr.replace(sensordata=sysid.TimeSeries(tr.sensordata.times - dt, tr.sensordata.data,
                                                       tr.sensordata.signal_mapping)) for tr in trajs]

    return sysid.build_residual_fn(models_sequences=sequences, custom_rollout=rollout,
                                   enabled_observations=enabled, sensor_weights=weights)


def _predictions(residual_fn: Any, params: Any, x: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
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


def _rms(residual_fn: Any, params: Any, x: np.ndarray, nu: int) -> list[list[float]]:
    return [[float(v) for v in np.sqrt(np.mean((me[:, :nu] - pr[:, :nu]) ** 2, axis=0))]
            for _, me, pr in _predictions(residual_fn, params, x)]


def _whitening(residual_fn: Any, opt: Any, nu: int, sensors: list[int]) -> np.ndarray:
    """Weights that make each kind of signal (angle, velocity, torque)
    count by its own noise, estimated from the fit's residual."""
    preds = _predictions(residual_fn, opt, opt.as_vector())
    # by position among the enabled sensors (a dict would be read by the
    # model's sensor index)
    weights = np.ones(len(sensors))
    for block in range(3):
        # the predictions' columns are the enabled sensors, in order
        cols = [p for p, s in enumerate(sensors) if s // nu == block]
        if not cols:
            continue
        err = np.concatenate([(me[:, cols] - pr[:, cols]).ravel() for _, me, pr in preds])
        sigma = max(float(np.std(err)), 1e-12)
        for p in cols:
            # sysid divides each column by its norm / sqrt(2): undo that, divide by sigma
            norm = np.linalg.norm(np.concatenate([me[:, p] for _, me, _ in preds])) / np.sqrt(2)
            weights[p] = float(norm / sigma) if norm > 0 else 1.0
    return weights


def _write(out: Path, res: FitResult, robot: Robot, logs: list[JointLog], labels: list[Any], x: np.ndarray,
           model: Any, names: list[str], per: str, force: bool) -> None:
    import mujoco

    from pupper_core._files import atomic_write

    out.mkdir(parents=True, exist_ok=True)

    def table(tmp: Path) -> None:
        with tmp.open("w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["parameter", "actuators", "nominal", "fitted", "low95", "high95", "unit"])
            for r in res.table:
                w.writerow([r["parameter"], r["actuators"], repr(r["nominal"]), repr(r["fitted"]),
                            repr(r["low95"]), repr(r["high95"]), r["unit"]])

    atomic_write(out / "fit.csv", table)

    def residuals(tmp: Path) -> None:
        with tmp.open("w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["log", "actuator", "rms_before_rad", "rms_after_rad"])
            for lg in logs:
                for k, a in enumerate(robot.actuators):
                    w.writerow([lg.path.name, a, repr(res.rms_before[lg.path.name][k]),
                                repr(res.rms_after[lg.path.name][k])])

    atomic_write(out / "residuals.csv", residuals)
    # the calibrated model: the full robot with the fitted values
    spec = mujoco.MjSpec.from_file(str(robot.file))
    # assets stay where the original's are
    base = robot.file.parent
    spec.meshdir = str((base / spec.meshdir).resolve()) if spec.meshdir else str(base)
    spec.texturedir = str((base / spec.texturedir).resolve()) if spec.texturedir else str(base)
    scales: dict[tuple[str, int], float] = {}
    n = _history_samples(robot)
    for (name, kind, members, _), v in zip(labels, x):
        for i in members:
            if kind in ("armature", "frictionloss"):
                setattr(spec.joint(robot.joints[i]), kind, float(v))
            elif kind == "damping":
                spec.joint(robot.joints[i]).damping[0] = float(v)
            elif kind == "delay":
                act = spec.actuator(robot.actuators[i])
                act.delay = float(v)
                act.nsample = n
                act.interp = 1
            else:
                scales[(kind, i)] = float(v)
    for (kind, i), v in sorted(scales.items()):
        spec.add_numeric(name=SCALE_NUMERIC.format(kind=kind, actuator=robot.actuators[i]), data=[v])
    spec.modelname = f"{spec.modelname}_calibrated" if spec.modelname else "calibrated"
    xml = spec.to_xml()
    atomic_write(out / "calibrated.xml", lambda tmp: tmp.write_text(xml))
    manifest = {
        "command": "fit",
        "inputs": {"model": str(model), "logs": [{"path": str(lg.path), "sha256": lg.sha256} for lg in logs],
                   "params": names, "per": per},
        "fit": {r["parameter"]: {"nominal": r["nominal"], "fitted": r["fitted"], "low95": r["low95"],
                                 "high95": r["high95"], "unit": r["unit"]} for r in res.table},
        "rms_before_rad": res.rms_before, "rms_after_rad": res.rms_after,
        "warnings": res.warnings, "seconds": res.seconds,
        "versions": {"mujoco": mujoco.__version__, "pupper": _version()},
    }
    atomic_write(out / "manifest.json", lambda tmp: tmp.write_text(json.dumps(manifest, indent=2) + "\n"))


def _version() -> str:
    from pupper_core import __version__

    return str(__version__)


def _plot(out: Path, robot: Robot, logs: list[JointLog], sequences: list[Any], residual_fn: Any, pdict: Any,
          x0: np.ndarray, opt: Any) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pupper_core._files import atomic_write

    nu = len(robot.actuators)
    first = _predictions(residual_fn, pdict, x0)
    last = _predictions(residual_fn, opt, opt.as_vector())
    (out / "plots").mkdir(exist_ok=True)
    wrote = []
    for lg, (t, me, p0), (_, _, p1) in zip(logs, first, last):
        cols = 4 if nu >= 4 else nu
        rows = math.ceil(nu / cols)
        fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 2.4 * rows), sharex=True, squeeze=False)
        for k in range(nu):
            ax = axes[k // cols][k % cols]
            ax.plot(t, me[:, k], color="black", lw=1.0, label="measured")
            ax.plot(t, p0[:, k], color="tab:gray", lw=0.8, ls="--", label="nominal model")
            ax.plot(t, p1[:, k], color="tab:orange", lw=0.8, label="fitted model")
            r0 = np.sqrt(np.mean((me[:, k] - p0[:, k]) ** 2)) * 1e3
            r1 = np.sqrt(np.mean((me[:, k] - p1[:, k]) ** 2)) * 1e3
            ax.set_title(f"{robot.actuators[k]}: RMS {r0:.2f} → {r1:.2f} mrad", fontsize=8)
            ax.tick_params(labelsize=7)
        axes[0][0].legend(fontsize=7, loc="upper right")
        for ax in axes[-1]:
            ax.set_xlabel("time (s)", fontsize=8)
        for row in axes:
            row[0].set_ylabel("angle (rad)", fontsize=8)
        fig.suptitle(f"{lg.path.name}: measured against simulated joint angle, before and after the fit", fontsize=10)
        fig.tight_layout()
        path = out / "plots" / f"fit_{lg.path.stem}.png"
        atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=90))
        plt.close(fig)
        wrote.append(path)
    return wrote


# ---------------------------------------------------------------------- CLI


def _cli_fit(args_json: str) -> list[str]:
    a = json.loads(args_json)
    res = fit(a.pop("logs"), **a)
    width = max(len(r["parameter"]) for r in res.table)
    print(f"{'parameter':<{width}}  {'nominal':>10}  {'fitted':>10}  {'95 % interval':>25}  unit")
    for r in res.table:
        print(f"{r['parameter']:<{width}}  {r['nominal']:>10.4g}  {r['fitted']:>10.4g}  "
              f"[{r['low95']:>10.4g}, {r['high95']:>10.4g}]  {r['unit']}")
    for name in res.rms_before:
        b, f = np.mean(res.rms_before[name]) * 1e3, np.mean(res.rms_after[name]) * 1e3
        print(f"{name}: RMS angle error {b:.3f} -> {f:.3f} mrad (mean over {len(res.actuators)} joints)")
    for w in res.warnings:
        print(f"warning: {w}", file=sys.stderr)
    print(f"fitted in {res.seconds:.1f} s")
    sys.stdout.flush()
    if res.out is None:
        return []
    wrote = [str(res.out / n) for n in ("fit.csv", "residuals.csv", "calibrated.xml")]
    if (res.out / "plots").is_dir():
        wrote += [str(p) for p in sorted((res.out / "plots").glob("fit_*.png"))]
    return wrote + [str(res.out / "report.html")]


def _cli_excite(args_json: str) -> list[str]:
    a = json.loads(args_json)
    path = excite(**a)
    sys.stdout.flush()
    return [str(path)]


def _hash(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()
