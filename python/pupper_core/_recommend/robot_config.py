"""The robot as it runs today, for `recommend`: its controller's
configuration (a ROS 2 parameter file: the node's joint order and gains),
the export's joint order, and the gains in use set beside the pick."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pupper_core._recommend.plan import Group, RecommendError


def current_gains(current: Sequence[float] | str | None, inf: Mapping[str, Any],
             groups: Sequence[Group]) -> tuple[dict[str, tuple[float, float]], str]:
    """The gains the robot runs today per group, and where they came from:
    `current` (KP,KD for every group), else the model's own servo gains
    (none for a model of motors)."""
    if current is None:
        acts = inf["actuators"]
        own = {}
        for g in groups:
            kp, kd = float(acts[g.actuators[0]]["gainprm"][0]), -float(acts[g.actuators[0]]["biasprm"][2])
            servo = kp > 0 and float(acts[g.actuators[0]]["biasprm"][1]) == -kp
            if not servo:
                return {}, ""
            own[g.name] = (kp, kd)
        return own, "the model's own"
    parts = current.split(",") if isinstance(current, str) else list(current)
    try:
        kp, kd = (float(v) for v in parts)
    except (TypeError, ValueError):
        raise RecommendError(f"--current {current!r} is not KP,KD: give the gains the robot runs today, "
                             "e.g. --current 5,0.25") from None
    if not (math.isfinite(kp) and kp > 0 and math.isfinite(kd) and kd >= 0):
        raise RecommendError(f"--current {kp:g},{kd:g}: give kp > 0 and kd >= 0, the gains the robot runs today")
    return {g.name: (kp, kd) for g in groups}, "--current"



def read_robot_config(path: Path, controller: str, names: Sequence[str]) -> tuple[list[str], list[float], list[float]]:
    """A robot's controller configuration (a ROS 2 parameter file, as the
    robot runs it): the `controller` node's joint_names and the gains it
    commands (kps/kds, else init_kps/init_kds)."""
    import yaml  # type: ignore[import-untyped]  # (PyYAML, with Optuna)

    where = f"--robot-config {path}"
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise RecommendError(f"{where}: cannot read it ({e.strerror}): give the robot's controller "
                             "configuration, a ROS 2 parameter YAML") from None
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise RecommendError(f"{where} is not YAML ({first}): give the robot's controller configuration, a ROS 2 "
                             "parameter file") from None
    node = doc.get(controller) if isinstance(doc, dict) else None
    params = node.get("ros__parameters") if isinstance(node, dict) else None
    if not isinstance(params, dict):
        nodes = ", ".join(k for k, v in doc.items() if isinstance(v, dict) and "ros__parameters" in v) \
            if isinstance(doc, dict) else ""
        raise RecommendError(f"{where} has no '{controller}: ros__parameters:' section: name the controller node "
                             f"with --controller{f' (its nodes: {nodes})' if nodes else ''}")
    joints = params.get("joint_names")
    kps = params.get("kps", params.get("init_kps"))
    kds = params.get("kds", params.get("init_kds"))
    for key, v in (("joint_names", joints), ("kps (or init_kps)", kps), ("kds (or init_kds)", kds)):
        if not isinstance(v, list) or not v:
            raise RecommendError(f"{where}: {controller}'s {key} is missing or not a list: give the controller's "
                                 "configuration as the robot runs it")
    assert isinstance(joints, list) and isinstance(kps, list) and isinstance(kds, list)
    if not len(joints) == len(kps) == len(kds):
        raise RecommendError(f"{where}: {controller} has {len(joints)} joint_names, {len(kps)} kps and {len(kds)} "
                             "kds: give one gain per joint")
    unknown = [str(j) for j in joints if j not in names]
    if unknown:
        raise RecommendError(f"{where} names joint '{unknown[0]}', which is not an actuator of the model: its "
                             f"actuators are {', '.join(names)}")
    try:
        return [str(j) for j in joints], [float(v) for v in kps], [float(v) for v in kds]
    except (TypeError, ValueError):
        raise RecommendError(f"{where}: {controller}'s kps and kds must be numbers") from None



def config_gains(config: tuple[list[str], list[float], list[float]], names: Sequence[str], groups: Sequence[Group],
                  path: Path) -> tuple[dict[str, tuple[float, float]], str]:
    """The gains a robot's configuration commands, per group (one kp and kd
    per group, as recommend answers)."""
    joints, kps, kds = config
    given = {n: (kp, kd) for n, kp, kd in zip(joints, kps, kds)}
    out = {}
    for g in groups:
        pairs = {given[names[a]] for a in g.actuators if names[a] in given}
        if len(pairs) > 1:
            raise RecommendError(f"--robot-config {path}: the {g.name} joints run different gains ({sorted(pairs)}): "
                                 "recommend compares one kp and kd per group; give --current KP,KD")
        if not pairs:
            return {}, ""
        kp, kd = pairs.pop()
        if not (math.isfinite(kp) and kp > 0 and math.isfinite(kd) and kd >= 0):
            raise RecommendError(f"--robot-config {path}: {g.name} runs kp {kp:g}, kd {kd:g}: give kp > 0 and kd >= 0")
        out[g.name] = (kp, kd)
    return out, f"{path.name}'s kps and kds"



def joint_order_of(order: Sequence[str] | str | None, names: list[str]) -> list[str]:
    if order is None:
        return list(names)
    entries = [s.strip() for s in (order.split(",") if isinstance(order, str) else order)]
    # an empty entry among names is a typo (two commas); no name at all is refused below
    if any(entries) and "" in entries[:-1]:
        raise RecommendError(f"--joint-order has an empty entry at position {entries.index('') + 1} (two commas?): "
                             "name each actuator once, comma-separated")
    got = [s for s in entries if s]
    unknown = [n for n in got if n not in names]
    if unknown:
        raise RecommendError(f"--joint-order names '{unknown[0]}', which is not an actuator of the model: "
                             f"its actuators are {', '.join(names)}")
    twice = next((n for i, n in enumerate(got) if n in got[:i]), None)
    if twice is not None:
        raise RecommendError(f"--joint-order names {twice} twice (at {got.index(twice) + 1} and "
                             f"{got.index(twice, got.index(twice) + 1) + 1}): name each actuator once")
    # the controller's kps and kds are one per joint: a joint left out would
    # be dropped from the file, silently
    if not got:
        raise RecommendError(f"--joint-order names no actuator: give the controller's order of all {len(names)} "
                             "actuators, comma-separated, or leave it out for the model's order")
    missing = [n for n in names if n not in got]
    if missing:
        shown = ", ".join(missing[:3]) + (", ..." if len(missing) > 3 else "")
        raise RecommendError(f"--joint-order names {len(got)} of the model's {len(names)} actuators: the YAML's kps "
                             f"and kds are one per joint of the controller; add {shown}")
    return got
