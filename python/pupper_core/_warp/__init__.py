"""The device side of the warp backend: MuJoCo Warp worlds for pupper's runner.

Only the Rust bridge (``bridge/warp.rs``) calls this module. A
:class:`Worlds` holds one compiled body (an ``MjModel`` the bridge prepared:
actuators fixed-gain with an affine bias, masses edited) as one Warp model
whose actuator gains, biases and force ranges and whose geom friction are
per world, and one Warp data with a world per simulation.
:meth:`Worlds.advance` steps every world ``k`` times -- each step the push,
``mujoco_warp.step`` and a record of qpos and actuator forces, captured once
as a graph and replayed -- and copies the records back in one block.
Metrics are computed from those records by the same Rust code as on the cpu
backend.

MuJoCo Warp (``mujoco-warp``, ``warp-lang``) is an optional extra; without
it the backend says what to install.
"""

from __future__ import annotations

import logging
import sys
from typing import Any

import numpy as np

INSTALL = (
    "install the optional extra: pip install 'pupper_core[gpu]' "
    "(in a pupper checkout: make setup PUPPER_EXTRAS=gpu)"
)

# Device memory for the records of one block of steps (qpos and actuator
# forces of every world, float32): bounds host and device memory per call.
RECORD_BYTES = 256 << 20

# Most worlds in one batch: a GPU's worth (the bare-loop peak on an H100 is
# at 65,536 worlds), and what a stop can lose (one batch) stays about a
# minute. The CPU device steps a few worlds at a time anyway.
MOST_WORLDS = {"cuda": 65536, "cpu": 256}

# What a world's masses change in a model: the masses and inertias, and what
# mj_setConst derives from them (MuJoCo Warp reads each batched field per
# world; its solver scales by each world's own mass matrix, not `stat`).
PER_WORLD_MASS = ("body_mass", "body_inertia", "body_subtreemass", "body_invweight0",
                  "dof_invweight0", "actuator_acc0")

#: Warp models built in this process: one per body geometry and batch.
MODELS_BUILT = 0

log = logging.getLogger("pupper_core.warp")


def mass_rows(model: Any) -> tuple[np.ndarray, ...]:
    """A body's fields of PER_WORLD_MASS (copies: the model may go)."""
    return tuple(np.array(getattr(model, f)) for f in PER_WORLD_MASS)


class WarpUnavailable(RuntimeError):
    """MuJoCo Warp is missing, or the device is not there."""


def _import() -> tuple[Any, Any]:
    try:
        import warp as wp  # type: ignore[import-not-found]

        # no banner, no per-module compile lines in pupper's output
        wp.config.log_level = wp.LOG_WARNING
        import mujoco_warp as mjw  # type: ignore[import-not-found]
    except ImportError as e:
        raise WarpUnavailable(
            f"the warp backend needs MuJoCo Warp, but the Python package "
            f"'{e.name}' is not installed in {sys.executable}: {INSTALL}"
        ) from None
    _init_quietly(wp)
    return wp, mjw


def _init_quietly(wp: Any) -> None:
    """``wp.init()``, minus the native warning every GPU-less machine gets
    ("Could not find or load the NVIDIA CUDA driver"): `pupper doctor` says
    which devices there are. Anything else Warp writes is passed on."""
    import os
    import tempfile

    if getattr(_init_quietly, "done", False):
        return
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as caught:
        os.dup2(caught.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        caught.seek(0)
        text = caught.read().decode(errors="replace")
    for line in text.splitlines():
        if line.strip() and "Could not find or load the NVIDIA CUDA driver" not in line:
            print(line, file=sys.stderr)
    _init_quietly.done = True  # type: ignore[attr-defined]


def versions() -> dict[str, str]:
    """Versions of warp-lang and mujoco-warp (raises WarpUnavailable)."""
    wp, mjw = _import()
    return {"warp": str(wp.config.version), "mujoco_warp": str(mjw.__version__)}


def devices() -> list[str]:
    """The Warp devices this machine has, e.g. ``["cpu", "cuda:0"]``, each
    with what it is (`pupper doctor`)."""
    wp, _ = _import()
    out = []
    for d in wp.get_devices():
        what = d.name
        if d.is_cuda:
            what += f", {d.total_memory / 2**30:.0f} GiB"
        out.append(f"{d.alias} ({what})")
    return out


def check(device: str) -> int:
    """Imports Warp and checks ``device``; returns the most worlds a batch
    should hold there."""
    wp, _ = _import()
    names = [d.alias for d in wp.get_devices()]
    if device == "cuda" and wp.is_cuda_available():
        device = str(wp.get_cuda_devices()[0].alias)
    if device not in names:
        seen = ", ".join(names)
        hint = (
            "use --device cpu (slow, for tests) or run on a machine with an NVIDIA GPU"
            if device.startswith("cuda")
            else "use one of those"
        )
        raise WarpUnavailable(f"Warp has no device '{device}' here (it sees: {seen}): {hint}")
    return MOST_WORLDS["cuda" if device.startswith("cuda") else "cpu"]


def _assign_per_world(m: Any, model: Any, n: int, actuators: tuple[np.ndarray, np.ndarray, np.ndarray],
                      floor: tuple[np.ndarray | None, list[int]], bodies: tuple[list[Any], np.ndarray] | None) -> None:
    """What differs between the device model's ``n`` worlds, in float32:
    each actuator's gains and force range, the floor's friction on the
    colliding geoms, and (``bodies``) each world's body constants."""
    f32 = np.float32
    gain, bias, force_range = actuators
    friction, colliding = floor
    gp = np.repeat(model.actuator_gainprm[None].astype(f32), n, axis=0)
    bp = np.repeat(model.actuator_biasprm[None].astype(f32), n, axis=0)
    gp[:, :, :3] = gain
    bp[:, :, :3] = bias
    m.actuator_gainprm.assign(gp)
    m.actuator_biasprm.assign(bp)
    m.actuator_forcerange.assign(np.ascontiguousarray(force_range, dtype=f32))
    if friction is not None:
        fr = np.repeat(model.geom_friction[None].astype(f32), n, axis=0)
        for g in colliding:
            fr[:, g, 0] = friction
        m.geom_friction.assign(fr)
    if bodies is not None:
        # the host's float64 constants of each body, rounded once:
        # the numbers a model of that body alone would carry
        rows, index = bodies
        for i, f in enumerate(PER_WORLD_MASS):
            per_world = np.stack([r[i] for r in rows])[np.asarray(index)]
            getattr(m, f).assign(np.ascontiguousarray(per_world, dtype=np.float32))


class Worlds:
    """One body's simulations on one Warp device, a world each.

    Arrays come from the bridge as float64: ``qpos`` (n, nq) and ``ctrl``
    (n, nu) start states; ``gain``/``bias`` (n, nu, 3) the first three
    actuator gain and bias parameters; ``force_range`` (n, nu, 2);
    ``friction`` (n,) the sliding friction of the ``colliding`` geoms, or
    None to keep the model's. ``bodies``: None when every world has the
    model's masses, else (rows, index): :func:`mass_rows` of the same body
    with other masses (``mj_setConst`` done on each) and each world's entry
    in that list; the
    one Warp model then holds each world's masses, inertias and the
    quantities MuJoCo derives from them, so a population of drawn robots
    (and the lab's heavy body beside the original) is one model.
    """

    def __init__(
        self,
        model: Any,
        device: str,
        keyframe: int,
        qpos: np.ndarray,
        ctrl: np.ndarray,
        gain: np.ndarray,
        bias: np.ndarray,
        force_range: np.ndarray,
        friction: np.ndarray | None,
        colliding: list[int],
        force_body: int,
        bodies: tuple[list[Any], np.ndarray] | None = None,
    ) -> None:
        import mujoco

        wp, mjw = _import()
        self._wp, self._mjw = wp, mjw
        self.device = wp.get_device(device)
        n = int(qpos.shape[0])
        self.n, self.nq, self.nu = n, model.nq, model.nu
        self.force_body = int(force_body)
        batched = {"actuator_gainprm": n, "actuator_biasprm": n, "actuator_forcerange": n}
        if friction is not None:
            batched["geom_friction"] = n
        if bodies is not None:
            batched.update({f: n for f in PER_WORLD_MASS})
        host = mujoco.MjData(model)
        if keyframe >= 0:
            mujoco.mj_resetDataKeyframe(model, host, keyframe)
        else:
            mujoco.mj_resetData(model, host)
        f32 = np.float32
        with wp.ScopedDevice(self.device):
            m = mjw.put_model(model, batch_sizes=batched)
            # bitwise the same numbers whatever the scheduling of the device
            m.opt.deterministic = int(mjw.DeterminismType.ALL)
            # a diverging world overflows its constraint rows every step:
            # the record kernel marks it diverged instead of Warp printing
            m.opt.warn_overflow = 0
            _assign_per_world(m, model, n, (gain, bias, force_range), (friction, colliding), bodies)
            d = mjw.put_data(model, host, nworld=n)
            d.qpos.assign(np.ascontiguousarray(qpos, dtype=f32))
            d.ctrl.assign(np.ascontiguousarray(ctrl, dtype=f32))
            self._q0 = wp.array(np.ascontiguousarray(qpos, dtype=f32), dtype=wp.float32)
            self.m, self.d = m, d
            # records of qpos and forces, and the moving targets' table
            per_step_bytes = n * (self.nq + 2 * self.nu) * 4
            self.block = max(1, min(1024, RECORD_BYTES // per_step_bytes))
            self._step = wp.zeros(1, dtype=wp.int32)
            self._per_step = wp.zeros(1, dtype=wp.int32)
            self._table = wp.zeros((self.block, n, 3), dtype=wp.float32)
            self._out_q = wp.zeros((self.block, n, self.nq), dtype=wp.float32)
            self._out_f = wp.zeros((self.block, n, self.nu), dtype=wp.float32)
            # moving targets (pupper response): each step's ctrl, when driven
            self._ctrl = wp.zeros((self.block, n, self.nu), dtype=wp.float32)
            self._driven = wp.zeros(1, dtype=wp.int32)
        self._graph: Any = None
        global MODELS_BUILT
        MODELS_BUILT += 1
        log.info("one Warp model for %d worlds (%d bodies of masses) on %s", n,
                 1 if bodies is None else len(bodies[0]), self.device)

    def _one_step(self) -> None:
        from pupper_core._warp import kernels as k

        wp, mjw = self._wp, self._mjw
        d = self.d
        push, record, tick = k.push, k.record, k.tick
        wp.launch(
            push,
            dim=self.n,
            inputs=[self._table, self._per_step, self._step, self.force_body, d.xfrc_applied],
        )
        wp.launch(k.drive, dim=(self.n, self.nu), inputs=[self._ctrl, self._driven, self._step, d.ctrl])
        mjw.step(self.m, d)
        wp.launch(
            record,
            dim=self.n,
            inputs=[
                d.qpos, d.qvel, d.qacc, d.qacc_warmstart, d.actuator_force,
                d.nefc, d.njmax, self._q0, self._step, self._out_q, self._out_f,
            ],
        )
        wp.launch(tick, dim=1, inputs=[self._step])

    def advance(self, k: int, forces: np.ndarray,
                ctrl: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Steps every world ``k`` (<= ``block``) times under ``forces`` on
        the base: (1, n, 3) held for every step, or (k, n, 3) one per step;
        ``ctrl`` (k, n, nu), when given, is every world's ctrl at each step
        (else ctrl stays as it is).
        Returns qpos (k, n, nq) and actuator forces (k, n, nu), float32; a
        world's row is NaN from the step its state diverged."""
        wp = self._wp
        if not 1 <= k <= self.block:
            raise ValueError(f"advance: k={k} is outside 1..{self.block}")
        rows = int(forces.shape[0])
        with wp.ScopedDevice(self.device):
            self._table[:rows].assign(np.ascontiguousarray(forces, dtype=np.float32))
            self._per_step.fill_(1 if rows > 1 else 0)
            if ctrl is not None:
                self._ctrl[:k].assign(np.ascontiguousarray(ctrl, dtype=np.float32))
            self._driven.fill_(0 if ctrl is None else 1)
            self._step.zero_()
            if self._graph is None:
                # one step (push, physics, record) captured once, replayed
                with wp.ScopedCapture(device=self.device) as capture:
                    self._one_step()
                self._graph = capture.graph
            for _ in range(k):
                wp.capture_launch(self._graph)
            q, f = self._out_q[:k].numpy(), self._out_f[:k].numpy()
            # contacts are one pool for all worlds: past it, worlds lose
            # contacts silently
            if int(self.d.nacon.numpy()[0]) > self.d.naconmax:
                raise RuntimeError(
                    f"MuJoCo Warp ran out of contacts ({self.d.naconmax} for "
                    f"{self.n} worlds): run fewer cells per batch (--chunk-cells)"
                )
            return q, f

    def qpos(self) -> np.ndarray:
        """Every world's qpos now, (n, nq) float32."""
        with self._wp.ScopedDevice(self.device):
            return self.d.qpos.numpy()
