"""A per-joint fit's cost (issue 38): the robot hangs from a welded base,
so its legs do not interact, and one rollout perturbs a parameter on every
leg at once. The Jacobian of 72 per-joint parameters then takes the 18
perturbed rollouts a per-group fit's 18 parameters take, and equals the
one finite differences give parameter by parameter."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pupper_core as pc
import pytest

pytest.importorskip("scipy", reason="the fit extra (make test installs it)")


def test_a_per_joint_jacobian_is_the_finite_difference_one_at_a_quarter_of_the_rollouts(tmp_path: Path):
    from mujoco.minimize import jacobian_fd

    from pupper_core._fit import _problem, _read_logs, _residual_fn, _sysid, load_robot
    from pupper_core._fit.terms import SERVO_FREE_PARAMS
    from pupper_core._fit.jacobian import colours, jacobian_fn, rollouts_per_jacobian

    log = pc.excite(out=tmp_path / "log.csv", seconds=0.5, hold=0.2)
    robot = load_robot("pupper_v3")
    sysid = _sysid()
    pb = _problem(sysid, robot, _read_logs([log], robot), list(SERVO_FREE_PARAMS), "joint")
    assert len(pb.labels) == 72 and len(colours(pb)) == 18 == rollouts_per_jacobian(robot, "joint", 6)
    calls = []
    fn = _residual_fn(sysid, pb.sequences, pb.enabled(sysid), None)

    def counted(x, params, **kw):
        calls.append(x.shape[1] if x.ndim > 1 else 1)
        return fn(x, params, **kw)

    jac = jacobian_fn(counted, pb.pdict, pb)
    assert jac is not None
    x = pb.pdict.as_vector().reshape(-1, 1)
    start = pb.pdict.copy()
    r = np.concatenate(fn(x, start)[0])
    got = jac(x, r)
    assert calls == [18]
    lo, hi = (b.reshape(-1, 1) for b in pb.pdict.get_bounds())
    want, _ = jacobian_fd(lambda z: np.concatenate(fn(z, start)[0]), x, r, np.finfo(float).eps ** 0.5, 0, [lo, hi])
    assert np.max(np.abs(got - want)) <= 1e-6 * np.max(np.abs(want))
    # a leg's parameter moves its own leg's signals only: the columns are not all zero, nor all full
    assert np.all(np.any(got != 0, axis=0)) and np.all(np.mean(got == 0, axis=0) > 0.5)
    # per group, every parameter spans the four legs: each needs its own rollout (sysid's own Jacobian)
    pbg = _problem(sysid, robot, _read_logs([log], robot), list(SERVO_FREE_PARAMS), "group")
    assert jacobian_fn(fn, pbg.pdict, pbg) is None and rollouts_per_jacobian(robot, "group", 6) == 18
