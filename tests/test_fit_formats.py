"""Logs in the formats robots write, and what validation reads from them
(issue 59, and issue 61 items 6, 12 and 14); each test fails on the code
before.

- One column map for every motor: ``motor=COLUMN`` names the log's motor
  (the model's actuator at that index, or of that name) and ``target=``,
  ``q=``, ``qd=``, ``tau=`` are that motor's; a unit in a column's own
  name (``command (rad)``, ``stamp (ms)``) is read as its unit; a Pupper
  v3's real2sim bench log needs no map at all.
- Validation reports a log's mean angle offset apart from its dynamic
  error, and reads a square-wave command as steps (rise time, overshoot).
- A hole in a log's time stamps, a parameter started with a unit
  (``--start lag=5ms``) and a log of millions of rows are each one line.

The logs are short and written here: excite's (1 s of the nominal model),
rewritten in a robot's format, or a designed response; only where the
point is a fit is one run (one parameter, two iterations)."""

from __future__ import annotations

import csv
import gzip
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pupper_core as pc
import pytest

from conftest import REPO, read_csv, write_hardware_log

sys.path.insert(0, str(REPO / "examples"))
from stand_log import MOTOR  # noqa: E402

pytest.importorskip("scipy", reason="the fit extra (make test installs it)")

REAL = REPO.parent / "shared" / "real_logs"
PATTERN = "kp_{kp}_kd_{kd}"
#: A Pupper v3 real2sim log's header (its ROS 2 loop's), and one map that reads every motor's log in it.
HEADER = ["time_since_fade_in (s)", "phase_", "amp (rad)", "freq (Hz)", "motor_idx", "policy_output",
          "command (rad)", "motor_position (rad)", "motor_velocity (rad/s)"]
MAP = ("time=time_since_fade_in (s),motor=motor_idx,target=command (rad),q=motor_position (rad),"
       "qd=motor_velocity (rad/s)")
#: The other motor of the tests: the left front hip, the model's actuator 3.
HIP = "leg_front_l_1"
QUICK = ["--params", "delay", "--max-iters", "2"]


def robot():
    from pupper_core._fit import load_robot

    return load_robot("pupper_v3")


def columns_of(log: Path) -> tuple[list[str], dict[str, np.ndarray]]:
    """A pupper-format log's ``#`` lines and its columns by name."""
    lines = log.read_text().splitlines()
    body = [ln for ln in lines if not ln.startswith("#")]
    header = body[0].split(",")
    data = np.array([[float(x) for x in ln.split(",")] for ln in body[1:]])
    return [ln for ln in lines if ln.startswith("#")], {h: data[:, j] for j, h in enumerate(header)}


def line(row: np.ndarray) -> str:
    return ",".join(repr(float(x)) for x in row)


def as_real2sim(log: Path, out: Path, motor: int, edit=None) -> Path:
    """``log`` (one actuator's, pupper's format) as a Pupper v3's bench tool
    writes it: gzipped, its header, the motor's index in ``motor_idx``, the
    gains only in the name; ``edit(rows)`` may change the rows first."""
    _, c = columns_of(log)
    act = next(h for h in c if h.endswith(".target")).rpartition(".")[0]
    rows = [[repr(float(t)), "0.0", "0.2", "1.0", str(motor), *(repr(float(v)) for v in (x, x, q, v))]
            for t, x, q, v in zip(c["time"], c[f"{act}.target"], c[f"{act}.q"], c[f"{act}.qd"])]
    if edit is not None:
        edit(rows)
    with gzip.open(out, "wt", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(HEADER)
        w.writerows(rows)
    return out


@pytest.fixture(scope="module")
def bench(tmp_path_factory) -> dict[str, Path]:
    """1 s of the knee (actuator 2) and of the left hip (actuator 3), each in
    pupper's format and as the bench writes it."""
    d = tmp_path_factory.mktemp("formats")
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for act, idx, seed in ((MOTOR, 2, 0), (HIP, 3, 1)):
            own = Path(pc.excite(out=d / f"{act}.csv", joints=act, seconds=0.6, hold=0.2, rate=250, seed=seed))
            out[act] = own
            out[idx] = as_real2sim(own, d / f"freq_sweep_motor_{idx}_kp_5_kd_0.1.csv.gz", idx)
    return out


def refused(path: Path, *words: str, **kw) -> str:
    """read_log's refusal of ``path``: one line holding ``words``."""
    from pupper_core._fit.columns import read_map
    from pupper_core._fit.log import LogError, read_log

    with pytest.raises(LogError) as e:
        if isinstance(kw.get("columns"), str):
            kw["columns"] = read_map(kw["columns"])
        read_log(path, robot().ranges, defaults={"kp": "5", "kd": "0.1"}, **kw)
    said = str(e.value)
    assert "\n" not in said and all(w in said for w in words), said
    return said


# -- item 1: one map for every motor, units in the names, the Pupper v3 format without a map --------------


def test_one_column_map_reads_the_log_of_every_motor(bench):
    """``motor=motor_idx`` with bare fields: each log is of the model's
    actuator at its motor's index, and reads the samples its pupper-format
    twin holds (the same content digest)."""
    from pupper_core._fit.columns import read_map
    from pupper_core._fit.problem import _read_logs

    read = _read_logs([bench[2], bench[3]], robot(), read_map(MAP), {"kp": None, "kd": None, "held": None},
                      pattern=PATTERN)
    assert [lg.logged for lg in read] == [[MOTOR], [HIP]]
    for lg, act in zip(read, (MOTOR, HIP)):
        own = _read_logs([bench[act]], robot())[0]
        assert lg.digest == own.digest and float(lg.kp[0]) == 5.0 and float(lg.kd[0]) == 0.1
    # the actuator's name works as the motor's too
    named = bench[2].parent / "named.csv.gz"
    as_real2sim(bench[MOTOR], named, 2, edit=lambda rows: [r.__setitem__(4, MOTOR) for r in rows])
    got = _read_logs([named], robot(), read_map(MAP), {"kp": "5", "kd": "0.1", "held": None})[0]
    assert got.logged == [MOTOR] and got.digest == read[0].digest


def test_a_unit_in_a_columns_name_is_its_unit(bench, tmp_path):
    """``stamp (ms)``, ``cmd (deg)``, ``vel (deg/s)``: read in those units
    where the map gives none; a map's unit that the name contradicts is
    one line."""
    from pupper_core._fit.log import read_log

    meta, c = columns_of(bench[MOTOR])
    names = {"time": "stamp (ms)", f"{MOTOR}.target": "cmd (deg)", f"{MOTOR}.q": "pos (deg)",
             f"{MOTOR}.qd": "vel (deg/s)"}
    scale = {"time": 1e3, f"{MOTOR}.target": 180 / math.pi, f"{MOTOR}.q": 180 / math.pi,
             f"{MOTOR}.qd": 180 / math.pi}
    rows = np.stack([c[k] * scale[k] for k in names], axis=1)
    own = tmp_path / "own.csv"
    own.write_text("\n".join(meta + [",".join(names.values())] + [line(r) for r in rows]) + "\n")
    cmap = ",".join(f"{k}={v}" for k, v in names.items())
    from pupper_core._fit.columns import read_map

    got = read_log(own, robot().ranges, columns=read_map(cmap))
    want = read_log(bench[MOTOR], robot().ranges)
    assert np.allclose(got.times, want.times, atol=1e-12) and np.allclose(got.q, want.q, atol=1e-12)
    assert np.allclose(got.qd, want.qd, atol=1e-12) and np.allclose(got.target, want.target, atol=1e-12)
    # the same unit said twice is no conflict; another is
    read_log(own, robot().ranges, columns=read_map(cmap.replace("pos (deg)", "pos (deg):deg")))
    refused(own, "'leg_front_r_3.q=pos (deg):rad'", "the map says rad, the column's name says deg",
            columns=cmap.replace("pos (deg)", "pos (deg):rad"))


def test_a_pupper_v3_bench_log_needs_no_map(bench, tmp_path, run):
    """The logs of two motors as the bench writes them, in one command with
    no map and no header lines: one note says how they were read, and each
    log is compared on its own motor."""
    a, b = bench[2], bench[3]
    p = run("fit", a, b, "--gains-from-name", PATTERN, *QUICK, "-o", tmp_path / "fit", check=0)
    said = [ln for ln in p.stderr.splitlines() if "Pupper v3 real2sim" in ln]
    assert len(said) == 1 and said[0].startswith(f"note: {a.name} (and any log like it)"), p.stderr
    assert "motor=motor_idx" in said[0] and "--columns" in said[0]
    _, rows = read_csv(tmp_path / "fit" / "residuals.csv")
    assert {(r["log"], r["actuator"]) for r in rows} == {(a.name, MOTOR), (b.name, HIP)}


def test_the_real_bench_logs_read_with_no_map(tmp_path):
    """A Pupper v3's own five logs: each of its motor (3, 4, 5: the left
    front hip, abduction and knee), the gains from the names."""
    if not REAL.is_dir():
        pytest.skip("../shared/real_logs is absent")
    from pupper_core._fit.problem import _read_logs

    logs = sorted(REAL.glob("freq_sweep_motor_*.csv.gz"))
    read = _read_logs(logs, robot(), None, {"kp": None, "kd": None, "held": None}, pattern=PATTERN)
    motors = {3: "leg_front_l_1", 4: "leg_front_l_2", 5: "leg_front_l_3"}
    for lg in read:
        assert lg.logged == [motors[int(lg.path.name.split("_")[3])]], lg.path.name
        assert float(lg.kd[0]) == 0.25 and lg.qd is not None and 19 < lg.duration < 23


def test_a_motor_column_that_is_no_motor_of_the_model_is_one_line(bench, tmp_path, run):
    """A motor past the model's actuators, a motor that changes within the
    log, bare fields with no motor column: each one line naming file,
    column and row."""
    past = as_real2sim(bench[MOTOR], tmp_path / "past.csv.gz", 12)
    p = run("fit", past, "--columns", MAP, "--kp", "5", "--kd", "0.1", *QUICK, "-o", tmp_path / "out", check=2)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "past.csv.gz, column 'motor_idx', row 2: motor 12 is past the model's 12 " \
        "actuators (0 to 11: leg_front_r_1 to leg_back_l_3)" in lines[0], p.stderr
    assert not (tmp_path / "out").exists()

    def switch(rows: list[list[str]]) -> None:
        for r in rows[100:]:
            r[4] = "4"

    changes = as_real2sim(bench[MOTOR], tmp_path / "changes.csv.gz", 2, edit=switch)
    refused(changes, "changes.csv.gz, column 'motor_idx', row 102: the motor changes (2, leg_front_r_3, to 4, "
            "leg_front_l_2)", "split the log where it changes")
    refused(bench[2], "'target=command (rad)' names no actuator", "motor=COLUMN",
            columns="time=time_since_fade_in (s),target=command (rad),q=motor_position (rad)")
    refused(bench[2], "the map says deg, the column's name says rad",
            columns=MAP.replace("q=motor_position (rad)", "q=motor_position (rad):deg"))


# -- item 4 of issue 61: a hole in the time stamps --------------------------------------------------------


def test_a_hole_in_the_time_stamps_is_one_line(bench, tmp_path, run):
    """5 s without a row in a 1 s recording (a logger that stopped) was
    replayed as a target held for 5 s; the ROS loop's jitter (4 ms, give
    or take 1.9) is no hole."""
    from pupper_core._fit.log import read_log

    meta, c = columns_of(bench[MOTOR])
    header = list(c)
    data = np.stack(list(c.values()), axis=1)
    data[150:, 0] += 5.0
    gap = tmp_path / "gap.csv"
    gap.write_text("\n".join(meta + [",".join(header)] + [line(r) for r in data]) + "\n")
    row = len(meta) + 2 + 150
    p = run("fit", gap, *QUICK, "-o", tmp_path / "out", check=2)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and f"gap.csv, column 'time', row {row}: the time jumps by 5.004 s" in lines[0] \
        and f"split the log at row {row} and give both parts" in lines[0], p.stderr
    assert not (tmp_path / "out").exists()
    rng = np.random.default_rng(0)
    data[:, 0] = np.cumsum(0.004 + rng.uniform(-0.0019, 0.0019, len(data)))
    data[100, 0] = data[99, 0] + 0.0095  # the real logs' longest step
    data[101:, 0] += 0.0095
    jitter = tmp_path / "jitter.csv"
    jitter.write_text("\n".join(meta + [",".join(header)] + [line(r) for r in data]) + "\n")
    assert len(read_log(jitter, robot().ranges).times) == len(data)


# -- item 12 of issue 61: a start value with a unit ------------------------------------------------------


def test_a_start_value_with_a_unit_says_the_number_to_write(tmp_path, run):
    p = run("fit", "x.csv", "--start", "lag=5ms", "-o", tmp_path / "out", check=2)
    assert p.stderr.strip() == ("error: --start lag=5ms is not a number: lag is in seconds; write it without the "
                                "unit: --start lag=0.005"), p.stderr
    for start, words in (({"delay": "15 ms"}, "--start delay=0.015"), ("latency=200us", "--start latency=0.0002"),
                         ("kp_scale=0.9x", "kp_scale is a plain ratio; write it without the unit: --start "
                                           "kp_scale=0.9"),
                         ("armature=2ms", "armature is in kg·m², not a time")):
        names = "armature,kp_scale,delay,latency"
        with pytest.raises(pc.ConfigError) as e:
            pc.fit("x.csv", params=names, start=start, progress=False)
        assert words in str(e.value), str(e.value)


# -- item 14 of issue 61: a log of millions of rows ------------------------------------------------------


def big_log(path: Path, rows: int, rate: float, bad_row: int | None = None) -> Path:
    """A log of one knee holding 0.1 rad, ``rows`` rows at ``rate`` Hz
    (time written to 10 us); ``bad_row``: a row whose angle is no number."""
    with path.open("w") as f:
        f.write(f"# kp: 5\n# kd: 0.1\ntime,{MOTOR}.target,{MOTOR}.q\n")
        for start in range(0, rows, 100_000):
            f.write("".join(f"{i / rate:.5f},0.1,{'x' if i == bad_row else '0.1'}\n"
                            for i in range(start, min(rows, start + 100_000))))
    return path


def test_a_log_of_two_million_rows_is_refused_as_it_is_read(tmp_path, run):
    """2,000,000 rows (500 s at 4 kHz) took 13-30 s and 1.3 GB to read,
    then a fit; it is refused at the row past the cap, the rest unread."""
    big = big_log(tmp_path / "big.csv", 2_000_000, 4000.0)
    started = time.monotonic()
    p = run("fit", big.name, "-o", tmp_path / "out", cwd=tmp_path, check=2)
    took = time.monotonic() - started
    lines = p.stderr.strip().splitlines()
    assert lines[-1] == ("error: big.csv, row 1000004: more than 1,000,000 rows, past what fit takes (its "
                         "Jacobians would outgrow the memory): split the log, or keep every k-th row (a servo's "
                         "motion needs 250 to 1000 rows a second)"), p.stderr
    # a read that takes long says so first, once
    assert all(ln.startswith("note: reading big.csv: ") for ln in lines[:-1]) and len(lines) <= 2, p.stderr
    assert took < 60 and not (tmp_path / "out").exists()


def test_a_log_past_600_s_is_refused_at_that_row(tmp_path, monkeypatch, capsys):
    """The 600 s a fit takes are counted as the rows come: a row past them
    is refused before any later row is read (a bad cell after it is never
    reached); a time column in ms is said to look like it; a long read
    says so once, on stderr."""
    import pupper_core._fit.log as fl

    # 10 Hz: 600.1 s after the first row at its row 6001 (line 6005), a bad cell at 6500
    refused(big_log(tmp_path / "long.csv", 7000, 10.0, bad_row=6500),
            "long.csv, column 'time', row 6005: the log runs past the 600 s fit takes (600.1 s after its first row)",
            "split a longer recording")
    refused(big_log(tmp_path / "ms.csv", 1000, 0.25), "ms.csv, column 'time', row 155",
            "its samples are 4 apart: the time column looks like milliseconds")
    monkeypatch.setattr(fl, "SLOW_READ_S", -1.0)
    read = fl.read_log(big_log(tmp_path / "slow.csv", 140_000, 1000.0), robot().ranges)
    assert len(read.times) == 140_000
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("note: reading ") and "65,536 rows" in err[0], err


# -- items 2 and 3 of issue 59: validation's offset, and a step log's response ----------------------------

#: validation.csv's columns before (docs and the report read them), then the new ones at the end
OLD = ["log", "actuator", "rms_nominal_rad", "rms_calibrated_rad", "bandwidth_hz_log", "bandwidth_hz_nominal",
       "bandwidth_hz_calibrated", "phase_2hz_deg_log", "phase_2hz_deg_nominal", "phase_2hz_deg_calibrated",
       "phase_5hz_deg_log", "phase_5hz_deg_nominal", "phase_5hz_deg_calibrated", "phase_10hz_deg_log",
       "phase_10hz_deg_nominal", "phase_10hz_deg_calibrated", "delay_left_s_nominal", "delay_left_s_calibrated"]
NEW = ["offset_nominal_rad", "offset_calibrated_rad", "rms_dynamic_nominal_rad", "rms_dynamic_calibrated_rad",
       "rise_time_s_log", "rise_time_s_nominal", "rise_time_s_calibrated", "overshoot_pct_log",
       "overshoot_pct_nominal", "overshoot_pct_calibrated"]
#: the step log's designed response: a second-order one at 8 Hz, damping ratio 0.5
WN, ZETA = 2 * math.pi * 8.0, 0.5


def unit_step(t: np.ndarray) -> np.ndarray:
    wd = WN * math.sqrt(1 - ZETA**2)
    s = 1 - np.exp(-ZETA * WN * t) * (np.cos(wd * t) + ZETA / math.sqrt(1 - ZETA**2) * np.sin(wd * t))
    return np.where(t >= 0, s, 0.0)


def square_log(path: Path) -> Path:
    """A 2 Hz square wave of +-0.2 rad on the knee after 0.3 s at rest, 500
    rows a second, its angle the designed response (each jump's, added)."""
    t = np.arange(0, 2.3, 0.002)
    x = np.where(t < 0.3, 0.0, np.where(((t - 0.3) // 0.25) % 2 == 0, 0.2, -0.2))
    jumps = np.flatnonzero(np.diff(x)) + 1
    q = sum(float(x[j] - x[j - 1]) * unit_step(t - t[j]) for j in jumps)
    return write_hardware_log(path, t, [MOTOR], x[:, None], np.asarray(q)[:, None], 5.0, 0.1)


def sine_log(path: Path) -> Path:
    """A stepped sine (1, 2, 3 Hz, a second each) on the knee, its angle a
    first-order lag (20 ms) of the command."""
    t = np.arange(0, 3.3, 0.002)
    x = sum(np.where((t >= 0.3 + k) & (t < 1.3 + k), 0.2 * np.sin(2 * np.pi * f * (t - 0.3 - k)), 0.0)
            for k, f in enumerate((1.0, 2.0, 3.0)))
    q = np.zeros_like(t)
    for i in range(1, len(t)):
        q[i] = q[i - 1] + (x[i - 1] - q[i - 1]) * (1 - math.exp(-0.002 / 0.02))
    return write_hardware_log(path, t, [MOTOR], np.asarray(x)[:, None], q[:, None], 5.0, 0.1)


def test_validation_reads_the_offset_apart_and_a_step_log_as_steps(bench, tmp_path, capsys):
    """A log whose angles sit 20 mrad off (an encoder's zero) is said as
    that offset with its dynamic error beside it; a square wave gets rise
    time and overshoot (the log's its designed response's) instead of NaN
    frequency figures; a stepped sine keeps its figures. The old columns
    keep their order, the new ones follow."""
    from pupper_core._fit.validate import print_table

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        other = Path(pc.excite(out=tmp_path / "other.csv", joints=MOTOR, seconds=0.6, hold=0.2, rate=250, seed=3))
    meta, c = columns_of(other)
    c[f"{MOTOR}.q"] = c[f"{MOTOR}.q"] + 0.02
    off = tmp_path / "offset.csv"
    off.write_text("\n".join(meta + [",".join(c)] + [line(r) for r in np.stack(list(c.values()), 1)])
                   + "\n")
    logs = [other, off, square_log(tmp_path / "square.csv"), sine_log(tmp_path / "sine.csv")]
    res = pc.fit(bench[MOTOR], params="kp_scale", max_iters=2, validate=logs, progress=False)
    rows = {r["log"]: r for r in res.validation}
    assert all(list(r) == OLD + NEW for r in res.validation), list(res.validation[0])
    for r in res.validation:
        for m in ("nominal", "calibrated"):
            # the mean square is the mean's square and the rest's
            assert r[f"rms_{m}_rad"] ** 2 == pytest.approx(r[f"offset_{m}_rad"] ** 2 + r[f"rms_dynamic_{m}_rad"] ** 2)
    for m in ("nominal", "calibrated"):
        assert rows["offset.csv"][f"offset_{m}_rad"] - rows["other.csv"][f"offset_{m}_rad"] == pytest.approx(0.02, abs=2e-3)
        # what is left is the replay's first moments, started 20 mrad off where the log's first row says
        assert rows["offset.csv"][f"rms_dynamic_{m}_rad"] < 0.2 * rows["offset.csv"][f"rms_{m}_rad"]
    offsets = {w.partition(":")[0] for w in res.warnings if "mrad off the calibrated model's on average" in w}
    assert "offset.csv" in offsets and "other.csv" not in offsets, res.warnings
    step, sine = rows["square.csv"], rows["sine.csv"]
    # the designed response: 90 % of a step within t90, its overshoot exp(-pi zeta / sqrt(1 - zeta^2))
    fine = np.arange(0, 0.2, 1e-6)
    t90 = float(fine[np.argmax(unit_step(fine) >= 0.9)])
    assert step["rise_time_s_log"] == pytest.approx(t90, abs=1e-3)
    assert step["overshoot_pct_log"] == pytest.approx(100 * math.exp(-math.pi * ZETA / math.sqrt(1 - ZETA**2)), abs=1.0)
    assert all(math.isfinite(step[f"{k}_{m}"]) for k in ("rise_time_s", "overshoot_pct") for m in ("nominal", "calibrated"))
    assert all(math.isnan(step[k]) for k in OLD[4:])
    assert math.isfinite(sine["bandwidth_hz_log"]) or math.isfinite(sine["phase_2hz_deg_log"])
    assert math.isnan(sine["rise_time_s_log"])
    assert not any(w.startswith("square.csv") and "response" in w for w in res.warnings), res.warnings
    assert {b["log"] for b in res.bode} == {"sine.csv"}
    print_table(res.validation)
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("validated log") and out[4].startswith("sine.csv")
    assert out[5].startswith("step log") and "rise time (ms)" in out[5] and out[7].startswith("square.csv")


def test_a_step_command_is_told_from_its_target():
    """A square wave is a step command; a sine (at the log's rate or held
    at a slower one), a stepped sine's fast steps and a constant are not.
    A first-order lag's 90 % rise time is its time constant times ln 10."""
    from pupper_core._fit.freq import jumps, step_response

    t = np.arange(0, 3.0, 0.002)
    square = np.where((t // 0.25) % 2 == 0, 0.3, -0.1)
    assert jumps(square) is not None and len(jumps(square)) == 11
    sine = np.sin(2 * np.pi * t)
    held = np.sin(2 * np.pi * np.floor(t / 0.01) * 0.01)
    fast = np.sin(2 * np.pi * 125 * t)
    for x in (sine, held, fast, np.zeros_like(t)):
        assert jumps(x) is None and step_response(t, x, x) is None
    tau = 0.015
    y = np.zeros_like(t)
    for i in range(1, len(t)):
        y[i] = y[i - 1] + (square[i - 1] - y[i - 1]) * (1 - math.exp(-0.002 / tau))
    y[0] = square[0]
    r = step_response(t, square, y)
    assert r is not None and r.jumps == 11
    assert r.rise_time == pytest.approx(tau * math.log(10), abs=1e-3) and r.overshoot_pct == pytest.approx(0, abs=1e-3)
