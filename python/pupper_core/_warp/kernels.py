"""The four small Warp kernels around a pupper step (see ``_warp``).

A module of its own, imported only once Warp is known to be installed:
Warp reads kernel annotations at definition time.
"""

import warp as wp

# the kernels' array types, each named once (as MuJoCo Warp names its own)
floats2d = wp.array2d(dtype=wp.float32)
floats3d = wp.array3d(dtype=wp.float32)
ints = wp.array(dtype=wp.int32)


@wp.kernel
def push(
    table: floats3d,
    per_step: ints,
    step: ints,
    body: int,
    xfrc: wp.array2d(dtype=wp.spatial_vector),
):
    """Writes the base's external force of this step (row 0 when held)."""
    w = wp.tid()
    k = step[0] * per_step[0]
    xfrc[w, body] = wp.spatial_vector(table[k, w, 0], table[k, w, 1], table[k, w, 2], 0.0, 0.0, 0.0)


@wp.kernel
def drive(
    table: floats3d,
    driven: ints,
    step: ints,
    ctrl: floats2d,
):
    """Writes this step's ctrl (moving targets), when the call drives it."""
    w, a = wp.tid()
    if driven[0] == 1:
        ctrl[w, a] = table[step[0], w, a]


@wp.func
def _huge(x: wp.float32) -> bool:
    # MuJoCo's own test for a diverged state (mj_checkPos/Vel/Acc)
    return not wp.isfinite(x) or wp.abs(x) > 1.0e10


@wp.kernel
def record(
    qpos: floats2d,
    qvel: floats2d,
    qacc: floats2d,
    warmstart: floats2d,
    force: floats2d,
    nefc: ints,
    njmax: int,
    q0: floats2d,
    step: ints,
    out_q: floats3d,
    out_f: floats3d,
):
    """Copies qpos and actuator forces into row ``step`` of the records.

    A world whose state diverged (not finite, or beyond 1e10, as MuJoCo
    tests it) or whose constraints overflowed njmax is recorded as NaN, and
    put back at its start at rest so that it stays harmless to the others
    (the runner ignores it from its first NaN on)."""
    w = wp.tid()
    j = step[0]
    bad = int(0)
    if nefc[w] > njmax:
        bad = int(1)
    for i in range(qvel.shape[1]):
        if _huge(qvel[w, i]) or _huge(qacc[w, i]):
            bad = int(1)
    for i in range(qpos.shape[1]):
        if _huge(qpos[w, i]):
            bad = int(1)
    for i in range(qpos.shape[1]):
        if bad != 0:
            out_q[j, w, i] = wp.nan
            qpos[w, i] = q0[w, i]
        else:
            out_q[j, w, i] = qpos[w, i]
    if bad != 0:
        for i in range(qvel.shape[1]):
            qvel[w, i] = 0.0
            warmstart[w, i] = 0.0
    for i in range(force.shape[1]):
        out_f[j, w, i] = force[w, i]


@wp.kernel
def tick(step: ints):
    """The next record row."""
    step[0] = step[0] + 1
