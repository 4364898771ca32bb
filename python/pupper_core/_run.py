"""The runs of the Rust core, below the package's facade
(``pupper_core/__init__.py`` re-exports them): the model's facts (info,
gains, pose), stand, sweep, response, hold, lab, merge and load_run, with
the report each run directory gets."""

from __future__ import annotations

import atexit
import os
import sys
import threading
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence, cast

if TYPE_CHECKING:
    from typing_extensions import Unpack

from pupper_core import _native
from pupper_core._native import SweepResult
from pupper_core._types import exported_from
from pupper_core._spec import DEFAULTS, Variant, parse_sine, sweep_options, with_spec_signature
from pupper_core._types import ModelInfo, SimOptions, StandReport, SweepOptions

# A sweep still running in a thread when the interpreter exits stops at
# its next check (finished cells kept) before Python tears threads down.
atexit.register(_native._shutdown)


def _stop_after_ctrl_c() -> None:
    """Python waits for non-daemon threads before exiting: when the main
    thread ended on Ctrl-C, their sweeps stop too instead of running on."""
    if isinstance(getattr(sys, "last_value", None), KeyboardInterrupt):
        _native._shutdown()


if hasattr(threading, "_register_atexit"):  # CPython >= 3.9: before the joins
    threading._register_atexit(_stop_after_ctrl_c)


@exported_from("pupper_core")
def info(model: str | os.PathLike[str] = "pupper_v3", variant: Variant = "original") -> ModelInfo:
    """Sizes, mass, joints, actuators (ctrl order), keyframes, sensors and
    legs (hip, knee, foot, measured on the compiled body) of a model, or of
    one of its named variants ("long-leg", "heavy")."""
    return _native.info(os.fspath(model), variant)


@exported_from("pupper_core")
@with_spec_signature(SimOptions, after="model")
def stand(model: str | os.PathLike[str] = DEFAULTS["model"], **options: Unpack[SimOptions]) -> StandReport:
    """Reset to a keyframe (or pose), stand with no push; final z, last-second std, tilt.

    Keywords are those of `pupper stand` (`--help` there), same defaults."""
    return _native.stand(**sweep_options({**options, "model": model}))


def _progress_printer() -> Callable[[int, int], None] | None:
    """A progress callback: tqdm in notebooks/terminals if installed, else none."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    bar = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            # tqdm's habit: nothing for a run shorter than a second, and
            # nothing in a script whose stderr is not a terminal (a log)
            shown = sys.stderr.isatty() or "ipykernel" in sys.modules
            bar = tqdm(total=total, unit="step", unit_scale=True, desc="pupper sweep",
                       delay=1.0, disable=not shown)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return update


@exported_from("pupper_core")
@with_spec_signature(SweepOptions, after="preset")
def sweep(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | Sequence[Mapping[str, float | str]]
    | str | None = None,
    *,
    preset: str | None = None,
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[int, int], None] = True,
    **options: Unpack[SweepOptions],
) -> SweepResult:
    """Run a grid of settings as one batched MuJoCo simulation.

    grid: {"kp": [10, 30], "kd": 1} (a value may also be text parsed as the
    CLI parses it: "10,30" or "1:120:16:log"), or the CLI's strings
    ["kp=10,30", "kd=1"] (or one such string), or cells one by one
    [{"kp": 10, "kd": 1}, {"kp": 30, "kd": 0.5, "name": "b"}] (not a product). preset: "chapter-4.6" or
    "lab-grid" (the lab's Kp x Kd grid only) instead of a grid. Every other keyword is the CLI flag of the same
    name, with the same default and checks (`pupper sweep --help`).
    out: also write the run directory (summary.csv, manifest.json, traces.csv)
    as `pupper sweep --out` does; resume=True continues an interrupted one.
    progress: True shows a tqdm bar when tqdm is installed; or a callable
    (done_steps, total_steps). Ctrl-C stops within a second, keeps what is
    finished, and raises KeyboardInterrupt.
    """
    callback = _progress_printer() if progress is True else (progress or None)
    return _with_report(_native.sweep(grid, preset=preset, out=out, progress=callback, **sweep_options(options)))


def _with_report(res: SweepResult) -> SweepResult:
    """Writes report.html into a finished run's directory."""
    if res.out is not None and res.complete:
        from pupper_core import _report

        _report.report(res.out)
    return res


@exported_from("pupper_core")
def report(run_dir: str | os.PathLike[str]) -> str:
    """Write ``run_dir/report.html`` (inputs, the table, plots, the best
    cells and the rule, warnings, links to the files beside it: one page,
    no network) from any run directory, as `pupper report DIR` does;
    returns its path. Every run with ``out`` writes one when it ends."""
    from pupper_core import _report

    return str(_report.report(run_dir))


@exported_from("pupper_core")
def response(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = None,
    *,
    signal: str = "step",
    amplitude: float = 0.2,
    frequency: float | None = None,
    chirp: Sequence[float] | str | None = None,
    hold: float = 0.5,
    joints: Sequence[str] | str = (),
    standing: bool = False,
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[int, int], None] = True,
    **options: Any,
) -> SweepResult:
    """How each joint follows its target, as `pupper response` runs it: every
    joint excited alone (its target steps by ``amplitude`` rad, or follows a
    sine of ``frequency`` Hz, or a logarithmic ``chirp`` F0,F1 Hz, after
    ``hold`` s at the stand pose) while the others hold, on the robot hung
    in the air (``standing=True``: on the floor), for every cell of
    ``grid`` in one batch.

    The result's table is summary.csv (each joint group's figures per
    cell); ``res.tables["response"]`` has a row per cell and joint (rise
    and settling time, overshoot, steady-state error; gain, phase,
    bandwidth), ``res.tables["bode"]`` the frequency response of a sine or
    chirp. ``joints``: groups (haa, hfe, kfe) or actuator names. Other
    keywords are `sweep`'s (model, mode, kp, kd, seconds (default 3),
    pose, replicates, threads, ...); see `pupper response --help` for the
    definitions.
    """
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"response() got unexpected keyword argument(s) {', '.join(unknown)}: "
                        "see help(pupper_core.response)")
    callback = _progress_printer() if progress is True else (progress or None)
    if isinstance(chirp, str):
        chirp = parse_sine(chirp)
    if isinstance(joints, str):
        joints = [j for j in joints.split(",") if j]
    elif isinstance(joints, Mapping):
        # iterating a dict gives its keys: a typo would pass as a joint list
        raise TypeError(f"joints must be a joint group or actuator name, or a list of them, not a dict "
                        f"({joints!r}): e.g. joints=['kfe'] or joints='haa,hfe'")
    return _with_report(_native.response(grid, out=out, progress=callback, signal=signal, amplitude=amplitude,
                            frequency=frequency, chirp=None if chirp is None else list(chirp),
                            hold=hold, joints=list(joints), standing=standing, **sweep_options(options)))


@exported_from("pupper_core")
def hold(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = None,
    *,
    load: float = 1.0,
    ramp: float = 2.0,
    shove: float = 0.25,
    shove_at: float | None = None,
    shove_duration: float = 0.25,
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[int, int], None] = True,
    **options: Any,
) -> SweepResult:
    """How firmly each cell of ``grid`` holds the robot up, as `pupper hold`
    runs it: the robot lands (1 s), a vertical load on its base ramps to
    ``load`` times its own weight (total mass times gravity, from the model)
    over ``ramp`` s and is held; 0.5 s after it is full (or at ``shove_at``)
    a sideways shove of ``shove`` times the weight acts for
    ``shove_duration`` s.

    The table (summary.csv) has the sweep's metrics per cell and the
    hold's: ``sag_mm`` (unloaded minus loaded base height, each the mean
    over 0.5 s), ``compliance_mm_per_n`` (sag per newton; lower is
    stiffer), ``sway_mm`` and ``recovery_s`` (the shove's sideways
    excursion, and the time until the base stays within 5 % of it of where
    it rests), ``torque_rms.GROUP`` (what each joint group spends holding
    the load) and, when the model declares each motor's ``pupper:kt:NAME``
    and ``pupper:resistance:NAME``, ``copper_w``. ``res.best()`` is the
    stiffest cell that stood. Other keywords are `sweep`'s (model, mode,
    kp, kd, seconds (default 7), pose, threads, motor, ...); see `pupper
    hold --help`.
    """
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"hold() got unexpected keyword argument(s) {', '.join(unknown)}: "
                        "see help(pupper_core.hold)")
    callback = _progress_printer() if progress is True else (progress or None)
    return _with_report(_native.hold(grid, out=out, progress=callback, load=load, ramp=ramp, shove=shove,
                                     shove_at=shove_at, shove_duration=shove_duration, **sweep_options(options)))


@exported_from("pupper_core")
def walk(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = None,
    *,
    gait: str = "trot",
    frequency: float = 2.0,
    speed: float = 0.25,
    sideways: float = 0.0,
    yaw_rate: float = 0.0,
    duty: float | None = None,
    step_height: float | None = None,
    height: float | None = None,
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[int, int], None] = True,
    **options: Any,
) -> SweepResult:
    """How well each cell of ``grid`` walks, as `pupper walk` runs it: the
    robot lands (1 s), moves its feet to the gait's stance (0.5 s), then
    walks ``gait`` (trot, walk, pace or bound) at ``frequency`` Hz, its
    commanded velocity (``speed`` forward and ``sideways`` in m/s,
    ``yaw_rate`` in rad/s) ramped up over 1 s, open loop: the feet placed
    by the gait (``duty``: the share of a cycle each foot is down, default
    0.6, 0.75 for walk; ``step_height`` in m, default 6 cm on Pupper's legs
    scaled to the model's), the joint targets from each leg's inverse
    kinematics on the model's own legs, at ``height`` m (default: the start
    pose's). The grid may vary the gains and the gait (frequency, speed,
    duty, step_height).

    The table (summary.csv) has the sweep's metrics per cell and the
    walk's over the steady window (the whole gait cycles from 3.5 s on):
    ``speed_ms``, ``speed_error_pct``, ``drift_ms``, ``yaw_drift_deg_s``,
    ``roll_rms_deg``, ``pitch_rms_deg``, ``height_std_mm``, ``slip_mm_s``,
    ``amplitude_ratio`` and ``lag_ms`` (the joints at the gait frequency),
    ``torque_rms``, ``power_w`` and ``cost_of_transport``; see
    docs/walk.md. ``res.best()`` is the cell that walks closest to the
    commanded velocity among those that stayed up. Other keywords are
    `sweep`'s (model, mode, kp, kd, seconds (default 8), pose, replicates,
    randomize, threads, motor, ...); see `pupper walk --help`.
    """
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"walk() got unexpected keyword argument(s) {', '.join(unknown)}: "
                        "see help(pupper_core.walk)")
    callback = _progress_printer() if progress is True else (progress or None)
    return _with_report(_native.walk(grid, out=out, progress=callback, gait=gait, frequency=frequency,
                                     speed=speed, sideways=sideways, yaw_rate=yaw_rate, duty=duty,
                                     step_height=step_height, height=height, **sweep_options(options)))


@exported_from("pupper_core")
def gains(model: str | os.PathLike[str] = "pupper_v3", *, kp: float | None = None, kd: float | None = None,
          bandwidth: float | None = None, damping: float = 0.7,
          pose: Sequence[float] | None = None, integrator: str | None = None,
          motor: str | None = None, sensing_delay: float | None = None) -> dict[str, Any]:
    """Servo gains for a ``bandwidth`` (Hz) and ``damping`` ratio per joint,
    or the natural frequency, damping ratio and stability margin of given
    ``kp`` and ``kd``, from each joint's inertia at ``pose`` (default: the
    stand pose), as `pupper gains --json` prints them. A stability margin
    of 1 or more is past the bound of the PD at the model's timestep as
    ``integrator`` (default: the model's own) takes its damping: the joint
    chatters or diverges there.

    With ``motor`` (a firmware spec as `--motor` takes it, e.g.
    ``"rate=500,filter=100"``) or ``sensing_delay`` (s), each joint and
    group also gets ``phase_margin_deg`` and ``gain_margin_db``: the
    margins of the loop that firmware closes (see `pupper gains --help`);
    below 0 degrees the real joint is unstable."""
    return cast("dict[str, Any]", _native.gains(os.fspath(model), kp=kp, kd=kd, bandwidth=bandwidth,
                                                 damping=damping,
                                                 pose=None if pose is None else [float(q) for q in pose],
                                                 integrator=integrator, motor=motor,
                                                 sensing_delay=sensing_delay))


@exported_from("pupper_core")
def pose(model: str | os.PathLike[str] = "pupper_v3", variant: Variant = "original",
         depth: float | None = None) -> dict[str, Any]:
    """The stand pose of a body, as `pupper pose --json` prints it: each
    leg's joint angles that put its foot ``depth`` m below the hip (default:
    the chapter's 0.14 m scaled to the model's legs)."""
    return cast("dict[str, Any]", _native.pose(os.fspath(model), variant, depth))


@exported_from("pupper_core")
def lab(
    variants: Variant | Sequence[Variant] | None = None,
    grid: Mapping[str, Any] | Sequence[str] | str | None = None,
    *,
    out: str | os.PathLike[str] | None = None,
    render: bool = False,
    progress: bool | Callable[[int, int], None] = True,
    **options: Any,
) -> SweepResult:
    """The chapter's lab, as `pupper lab` runs it: every body (default
    original, long-leg, heavy) from a stand pose searched on its own body,
    Kp 10,30,60,120 x Kd 0.5,1,2,5 (or `grid`, CLI strings) in torque mode
    under a 2 N, 1.2 Hz vertical sine force, 6 s, no push, in one batch.

    `res.best(by=["variant"])` gives each body's steadiest gains (by
    last_1s_std_mm, or p95:last_1s_std_mm over replicates). With `out`, the run directory also gets best.csv, the lab's
    figures and (where OpenGL works) the bodies drawn at their best gains;
    `render=True` adds the GIF. Other keywords: seconds, sine, model,
    force, resume, threads, max_saturation, rank, backend, device, ray, motor
    (the servo firmware of the lab's torque-mode PD, as `sweep`'s), depth
    (the feet's depth below the hips in m; default the chapter's 0.14 m scaled
    to the model's legs), and the
    population (replicates, seed, randomize) as `sweep` takes them (defaults as
    `pupper lab --help`).
    """
    callback = _progress_printer() if progress is True else (progress or None)
    if isinstance(options.get("sine"), str):
        options["sine"] = parse_sine(options["sine"])
    res = _native.lab(_names(variants), _grid_specs(grid), out=out, progress=callback, **options)
    if res.out is not None:
        from pupper_core.plots.lab import write_lab_plots
        from pupper_core.render import RenderUnavailable, write_lab_effects

        write_lab_plots(res.out)
        try:
            write_lab_effects(res.out, gif=render)
        except RenderUnavailable:
            if render:
                raise
    return _with_report(res)


def _names(variants: str | Sequence[str] | None) -> list[str] | None:
    """Body names: one name or several (a string is one name, never its letters)."""
    if variants is None:
        return None
    return [variants] if isinstance(variants, str) else [str(v) for v in variants]


def _grid_specs(grid: Any) -> list[str] | None:
    """The lab's grid as CLI strings, from what `sweep` takes: a dict of
    axis -> values (numbers or text), `AXIS=VALUES` strings, or one."""
    if grid is None:
        return None
    if isinstance(grid, str):
        return [grid]
    if isinstance(grid, Mapping):
        def one(v: Any) -> str:
            if isinstance(v, str) or (isinstance(v, int) and not isinstance(v, bool)):
                return str(v)
            return repr(float(v))  # numpy scalars too: the shortest exact text

        def text(values: Any) -> str:
            if isinstance(values, (str, int, float)):
                return one(values)
            return ",".join(one(v) for v in values)

        return [f"{axis}={text(values)}" for axis, values in grid.items()]
    return [str(g) for g in grid]


@exported_from("pupper_core")
def merge(dirs: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str], *,
          force: bool = False) -> SweepResult:
    """Puts the shards of one sweep (each run with ``shard="I/N"``) together
    into the run directory `out`, as `pupper merge` does: its summary.csv is
    the unsharded sweep's. Refuses shards of different sweeps, a missing or
    repeated shard (saying which to rerun)."""
    if isinstance(dirs, (str, os.PathLike)):
        dirs = [dirs]  # one directory, never its characters
    return _native.merge([os.fspath(d) for d in dirs], os.fspath(out), force=force)


@exported_from("pupper_core")
def load_run(run_dir: str | os.PathLike[str]) -> SweepResult:
    """A SweepResult from a run directory written by `pupper sweep` or
    sweep(out=...); its rows are checked against its manifest's grid."""
    return _native.load_run(os.fspath(run_dir))
