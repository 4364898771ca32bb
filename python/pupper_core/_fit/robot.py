"""The robot a fit sees (``pupper_core._fit`` fits it): a model's
actuators, their joints, groups, ranges, limits and nominal parameters,
and the robot hung in the air at given gains, simulated from a log's start."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._run import info as model_info
from pupper_core._fit.terms import GROUPS, PARAMS, FitError

#: The built-in models: their file, and whether the base is welded.
BUILTINS = {"pupper_v3": ("pupper_v3/scene.xml", False), "pupper_v3_fixed": ("pupper_v3/pupper_v3.xml", True)}


def _model_file(model: str | os.PathLike[str]) -> tuple[Path, bool]:
    """A model's file, and whether its base is welded to the world (the
    built-in pupper_v3_fixed: the robot file, free joint removed)."""
    p = Path(model)
    if p.is_file():
        return p.resolve(), False
    if str(model) in BUILTINS:
        rel, fixed = BUILTINS[str(model)]
        return Path(__file__).parent.parent / "models" / rel, fixed
    raise FitError(f"model '{model}' is neither an MJCF file nor a built-in model "
                   f"({', '.join(BUILTINS)}): give --model PATH or pupper_v3")


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
    #: each joint's inertia at rest (kg·m², armature included)
    inertia: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: the base welded to the world (pupper_v3_fixed): calibrated.xml keeps it so
    fixed_base: bool = False
    #: each actuator's leg (-1: none): hung from a welded base, legs do not interact
    legs: list[int] = field(default_factory=list)
    #: the bodies (whole legs) the replay leaves out of the model: no log moves them
    dropped: tuple[str, ...] = ()
    #: the whole robot this one is a part of (``narrow``); None: it is the whole robot
    whole: Robot | None = None

    @property
    def full(self) -> Robot:
        """The whole robot (calibrated.xml is written over it)."""
        return self.whole if self.whole is not None else self

    def natural_hz(self, kp: np.ndarray) -> np.ndarray:
        """Each joint's natural frequency (Hz) at stiffness ``kp``."""
        return np.asarray(np.sqrt(np.asarray(kp) / self.inertia) / (2 * math.pi))

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

    path, fixed = _model_file(model)
    try:
        m = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as e:
        raise FitError(f"model '{path}' does not compile ({str(e).splitlines()[0]}): fix the MJCF") from None
    info = model_info(str(path))
    group_of: dict[int, str] = {}
    leg_of: dict[int, int] = {}
    for li, leg in enumerate(info["legs"]):
        for k, leg_joint in enumerate(leg["joints"]):
            group_of[leg_joint] = GROUPS[min(k, 2)]
            leg_of[leg_joint] = li
    acts, joints, groups, ranges, limits, legs = [], [], [], {}, [], []
    own_kp, own_kd, arm, damp, fric, rest = [], [], [], [], [], []
    key: int | None = next((k for k in range(m.nkey)
                            if mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_KEY, k) == "home"), None)
    for a, ai in enumerate(info["actuators"]):
        j = ai["joint"]
        if j is None:
            raise FitError(f"actuator '{ai['name']}' drives no joint: fit needs joint actuators")
        jid = int(m.actuator_trnid[a, 0])
        acts.append(ai["name"])
        joints.append(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, jid))
        groups.append(group_of.get(j, "joint"))
        legs.append(leg_of.get(j, -1))
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
                 float(m.opt.timestep), _inertia(m, joints, rest), fixed, legs)


def narrow(robot: Robot, moved: set[str]) -> Robot:
    """The robot with only the legs that hold an actuator in ``moved``:
    hung from a welded base, a leg no log covers neither moves nor touches
    the others, so the replay leaves it out (a one-motor log of the
    12-joint Pupper steps a quarter of the joints and friction
    constraints: 4 times faster). The whole robot where the model names
    no legs, a leg's subtree holds another's joint, or the reduced model
    does not compile."""
    import mujoco

    if not robot.legs or -1 in robot.legs or robot.whole is not None:
        return robot
    keep_legs = {robot.legs[k] for k, a in enumerate(robot.actuators) if a in moved}
    keep = [k for k in range(len(robot.actuators)) if robot.legs[k] in keep_legs]
    if not keep or len(keep) == len(robot.actuators):
        return robot
    m = mujoco.MjModel.from_xml_path(str(robot.file))
    jid = {j: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in robot.joints}
    body_leg: dict[int, int] = {int(m.jnt_bodyid[jid[j]]): robot.legs[k] for k, j in enumerate(robot.joints)}
    roots: list[str] = []
    for leg in sorted(set(robot.legs) - keep_legs):
        bodies = {b for b, lg in body_leg.items() if lg == leg}
        top = [b for b in bodies if int(m.body_parentid[b]) not in bodies]
        if len(top) != 1:
            return robot
        # the subtree below the leg's root: it must hold no joint of a kept leg
        sub = {top[0]}
        for b in range(m.nbody):
            p = b
            while p > 0 and p not in sub:
                p = int(m.body_parentid[p])
            if p in sub:
                sub.add(b)
        if any(body_leg.get(b, leg) != leg for b in sub):
            return robot
        roots.append(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, top[0]))
    part = Robot(robot.file, [robot.actuators[k] for k in keep], [robot.joints[k] for k in keep],
                 [robot.groups[k] for k in keep], {robot.actuators[k]: robot.ranges[robot.actuators[k]] for k in keep},
                 robot.limits[keep], robot.own_kp[keep], robot.own_kd[keep], robot.armature[keep],
                 robot.damping[keep], robot.frictionloss[keep], robot.rest[keep], robot.timestep,
                 robot.inertia[keep], robot.fixed_base, [robot.legs[k] for k in keep], tuple(roots), robot)
    try:
        suspended_spec(part, part.own_kp, part.own_kd).compile()
    except ValueError:
        return robot
    return part


def _inertia(m: Any, joints: list[str], rest: list[float]) -> np.ndarray:
    """Each joint's own inertia at the rest pose: its diagonal of the mass
    matrix (the same whether the base is free or welded)."""
    import mujoco

    d = mujoco.MjData(m)
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints]
    for jid, q in zip(ids, rest):
        d.qpos[m.jnt_qposadr[jid]] = q
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    return np.array([max(float(full[m.jnt_dofadr[j], m.jnt_dofadr[j]]), 1e-12) for j in ids])


def _history_samples(robot: Robot) -> int:
    return int(math.ceil(PARAMS["delay"][2] / robot.timestep)) + 3


def suspended_spec(robot: Robot, kp: np.ndarray, kd: np.ndarray, firmware: bool = False) -> Any:
    """The robot hung in the air at the given gains, sensing each actuated
    joint's angle, velocity and actuator force (sensors in that order).
    ``firmware``: its actuators plain torque motors, the gains and the
    command delay kept for the firmware's replay (``firmware``)."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(robot.file))
    for j in list(spec.joints):
        if j.type == mujoco.mjtJoint.mjJNT_FREE:
            spec.delete(j)
    for k in list(spec.keys):
        spec.delete(k)
    for s in list(spec.sensors):
        spec.delete(s)
    if robot.dropped:
        kept = set(robot.actuators)
        for a in [a for a in spec.actuators if a.name not in kept]:
            spec.delete(a)
        for name in robot.dropped:
            spec.delete(spec.body(name))
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    n = _history_samples(robot)
    for i, name in enumerate(robot.actuators):
        act = spec.actuator(name)
        if firmware:
            _torque_motor(act, kp[i], kd[i])
            continue
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


def _torque_motor(act: Any, kp: float, kd: float) -> None:
    """An actuator as a plain torque motor, the firmware's gains and command
    delay in its unused gain parameters (gainprm[1:4])."""
    import mujoco

    from pupper_core._fit.replay import DELAY_SLOT, KD_SLOT, KP_SLOT

    act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    act.biastype = mujoco.mjtBias.mjBIAS_NONE
    act.gainprm[:] = 0.0
    act.biasprm[:] = 0.0
    act.gainprm[0] = 1.0
    act.gainprm[KP_SLOT], act.gainprm[KD_SLOT], act.gainprm[DELAY_SLOT] = kp, kd, 0.0
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE


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
