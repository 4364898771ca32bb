"""Logs as they come off a robot (issue 47, item 3), and round 4 of trust
for `pupper fit` and `pupper excite`'s inputs (issue 49: items 9, 10, 12,
15, 22, 23, 24; each test named by its item fails on the code before).

A robot's bench tool writes gzipped CSVs with the gains only in the file
name (`freq_sweep_motor_3_..._kp_5_kd_0.25.csv.gz`): they are read as they
are, each log with its own gains and column map, in one command. The
stand-in logs are examples/stand_log.py's (a plain MuJoCo loop), gzipped
as the bench's tool does; the real ones (../shared/real_logs/, a Pupper
v3's left front leg) are read where that folder is present."""

from __future__ import annotations

import bz2
import gzip
import json
import lzma
import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pupper_core as pc
import pytest

from conftest import REPO, clean_env, read_csv

sys.path.insert(0, str(REPO / "examples"))
from stand_log import MOTOR, stand_log  # noqa: E402

pytest.importorskip("scipy", reason="the fit extra (make test installs it)")

REAL = REPO.parent / "shared" / "real_logs"
#: the stand's map without its gain columns: the gains come from the names, as on the bench
KNEE_MAP = (f"time=stamp\n{MOTOR}.target=fr_knee_cmd\n{MOTOR}.q=fr_knee_pos\n{MOTOR}.qd=fr_knee_vel\n")
PATTERN = "kp_{kp}_kd_{kd}"
QUICK = ["--params", "delay", "--max-iters", "1"]


def one_line(p: subprocess.CompletedProcess[str], *words: str) -> str:
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and all(w in lines[0] for w in words), p.stderr
    assert lines[0].startswith("error: ") and "internal error" not in lines[0], p.stderr
    assert "Traceback" not in p.stderr
    return lines[0]


@pytest.fixture(scope="module")
def bench(tmp_path_factory) -> Path:
    """The stand's knee as the bench writes it: gzipped, the gains in the
    names, kp 5 at kd 0.1 and 0.3 to fit, kp 7.5 to check; and its map."""
    d = tmp_path_factory.mktemp("bench")
    for kp, kd, seed in ((5.0, 0.1, 0), (5.0, 0.3, 1), (7.5, 0.1, 4)):
        stand_log(d / f"freq_sweep_knee_kp_{kp:g}_kd_{kd:g}.csv.gz", kp=kp, kd=kd, seed=seed, gzip=True)
    (d / "knee.map").write_text(KNEE_MAP)
    return d


@pytest.fixture(scope="module")
def short(tmp_path_factory) -> Path:
    """A short log of one knee at 250 Hz in pupper's own format (the
    nominal model's response; its header says kp 5, kd 0.1)."""
    d = tmp_path_factory.mktemp("short")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Path(pc.excite(out=d / "short.csv", joints=MOTOR, seconds=0.6, hold=0.2, rate=250))


def without_gains(log: Path, out: Path) -> Path:
    out.write_text("".join(ln for ln in log.read_text().splitlines(keepends=True)
                           if not ln.startswith(("# kp:", "# kd:"))))
    return out


def robot():
    from pupper_core._fit import load_robot

    return load_robot("pupper_v3")


# -- logs as they come off the robot (issue 47, item 3) ---------------------------------------


def test_a_compressed_log_is_read_by_its_bytes_whatever_its_name(short, tmp_path):
    """gzip, bzip2 and xz are read directly, told by their magic bytes (a
    .csv that is gzipped too); the samples are the plain log's, and so is
    the content digest (its bytes' SHA-256 differs). Never "binary"."""
    from pupper_core._joint_log import LogError, read_log

    ranges = robot().ranges
    plain = read_log(short, ranges)
    raw = short.read_bytes()
    packed = {"a.csv.gz": gzip.compress(raw), "b.csv": gzip.compress(raw), "c.bz2": bz2.compress(raw),
              "d.csv.xz": lzma.compress(raw), "e": lzma.compress(raw), "f.csv.gz.gz": gzip.compress(gzip.compress(raw))}
    for name, data in packed.items():
        (tmp_path / name).write_bytes(data)
        got = read_log(tmp_path / name, ranges)
        assert np.array_equal(got.times, plain.times) and np.array_equal(got.q, plain.q), name
        assert np.array_equal(got.kp, plain.kp) and got.actuators == plain.actuators == [MOTOR]
        assert got.digest == plain.digest and got.sha256 != plain.sha256, name
    (tmp_path / "cut.csv.gz").write_bytes(gzip.compress(raw)[:400])
    (tmp_path / "x.zst").write_bytes(b"\x28\xb5\x2f\xfd" + raw[:40])
    for name, words in (("cut.csv.gz", "gzip-compressed but does not decompress"),
                        ("x.zst", "zstd-compressed, which fit does not read")):
        with pytest.raises(LogError) as e:
            read_log(tmp_path / name, ranges)
        assert words in str(e.value) and "binary" not in str(e.value), str(e.value)


def test_the_stand_gzips_its_log_as_the_bench_tool_does(bench):
    """The bench's files are `gzip -n -9`: no name, no time stamp, maximum
    compression, written on Unix. The stand's are the same kind of file."""
    head = (bench / "freq_sweep_knee_kp_5_kd_0.1.csv.gz").read_bytes()[:10]
    assert head == bytes.fromhex("1f8b0800000000000203")
    if REAL.is_dir():
        real = next(REAL.glob("*.csv.gz")).read_bytes()[:10]
        assert real == head


def test_gains_from_names_per_log_options_and_a_list_say_the_same(bench, tmp_path, run):
    """One command, no file edited: the gains read from each name by a
    pattern, given per log (LOG::kp=,kd=), or in a list file, fit the same
    numbers byte for byte; the validation log at kp 7.5 runs at its own."""
    fit, chk = ["freq_sweep_knee_kp_5_kd_0.1.csv.gz", "freq_sweep_knee_kp_5_kd_0.3.csv.gz"], \
        "freq_sweep_knee_kp_7.5_kd_0.1.csv.gz"
    quick = ["--params", "kp_scale", "--max-iters", "1"]
    run("fit", *fit, "--columns", "knee.map", "--gains-from-name", PATTERN, "--validate", chk, *quick,
        "-o", tmp_path / "by_name", cwd=bench, check=0)
    run("fit", f"{fit[0]}::kp=5,kd=0.1", f"{fit[1]}::kd=0.3::kp=5", "--columns", "knee.map", "--validate",
        f"{chk}::kp=7.5,kd=0.1", *quick, "-o", tmp_path / "per_log", cwd=bench, check=0)
    sub = tmp_path / "lists"
    sub.mkdir()
    (sub / "bench.logs").write_text(
        "# the knee on the stand, kp 5\n"
        f"../../{bench.name}/{fit[0]}::kp=5,kd=0.1,columns=knee.map\n\n"
        f"{bench / fit[1]}::kp=5,kd=0.3,columns={bench / 'knee.map'}\n")
    (sub / "knee.map").write_text(KNEE_MAP)
    (sub / "check.logs").write_text(f"{bench / chk}::kp=7.5,kd=0.1\n")
    p = run("fit", "@lists/bench.logs", "--validate", "@lists/check.logs", "--columns", bench / "knee.map",
            *quick, "-o", tmp_path / "listed", cwd=tmp_path, check=0)
    assert f"{fit[0]}: RMS angle error" in p.stdout, p.stdout
    first = (tmp_path / "by_name" / "fit.csv").read_bytes()
    for other in ("per_log", "listed"):
        assert (tmp_path / other / "fit.csv").read_bytes() == first, other
        assert ((tmp_path / other / "validation.csv").read_bytes()
                == (tmp_path / "by_name" / "validation.csv").read_bytes()), other
    _, rows = read_csv(tmp_path / "by_name" / "validation.csv")
    assert [r["log"] for r in rows] == [chk] and rows[0]["actuator"] == MOTOR
    manifest = json.loads((tmp_path / "by_name" / "manifest.json").read_text())
    assert [Path(lg["path"]).name for lg in manifest["inputs"]["logs"]] == fit


def test_each_log_has_its_own_map_and_it_names_the_log_s_motors(bench, tmp_path):
    """Logs of different motors in one command: each log's map names the
    actuators it covers (here one recording read as the right and as the
    left knee), its own map in place of --columns."""
    from pupper_core._fit_problem import _read_logs
    from pupper_core._log_columns import read_map

    left = tmp_path / "left.map"
    left.write_text(KNEE_MAP.replace(MOTOR, "leg_front_l_3"))
    logs = [f"{bench / 'freq_sweep_knee_kp_5_kd_0.1.csv.gz'}::columns={left}",
            bench / "freq_sweep_knee_kp_5_kd_0.3.csv.gz"]
    read = _read_logs(logs, robot(), read_map(str(bench / "knee.map")), {"kp": None, "kd": None, "held": "0"},
                      pattern=PATTERN)
    assert [lg.logged for lg in read] == [["leg_front_l_3"], [MOTOR]]
    assert [float(lg.kd[0]) for lg in read] == [0.1, 0.3] and all(float(lg.kp[0]) == 5.0 for lg in read)
    # the held angle: every joint the log does not cover holds 0
    i = read[0].actuators.index(MOTOR)
    assert np.all(read[0].q[:, i] == 0.0) and np.ptp(read[1].q[:, i]) > 0.1


@pytest.mark.parametrize("args, words", [
    (["x.csv::kq=5"], ("LOG 'x.csv::kq=5'", "'kq=5' is not one of the log's options kp, kd, held, columns")),
    (["x.csv::kp="], ("kp= has no value",)),
    (["::kp=5"], ("names no log before '::'",)),
    (["x.csv::kp=5,kp=6"], ("kp is given twice",)),
    (["@none.logs"], ("@none.logs: cannot read the list of logs (No such file or directory)",)),
    (["x.csv", "--gains-from-name", "kp"], ("--gains-from-name 'kp' has neither {kp} nor {kd}",)),
    (["x.csv", "--gains-from-name", "kp_{kq}"], ("{kq} is neither {kp} nor {kd}",)),
    (["x.csv", "--gains-from-name", "{kp}_{kp}"], ("names {kp} twice",)),
])
def test_a_log_named_wrong_is_one_line(tmp_path, run, args, words):
    p = run("fit", *args, "-o", tmp_path / "out", check=2)
    one_line(p, *words)
    assert not (tmp_path / "out").exists()


def test_a_list_and_a_name_the_pattern_reads_twice_are_refused(bench, tmp_path, run):
    (tmp_path / "empty.logs").write_text("# nothing yet\n\n")
    (tmp_path / "nested.logs").write_text("@empty.logs\n")
    twice = tmp_path / "kp_5_kd_0.1_kp_7_kd_0.1.csv.gz"
    twice.write_bytes((bench / "freq_sweep_knee_kp_5_kd_0.1.csv.gz").read_bytes())
    for args, words in ((["@empty.logs"], ("@empty.logs names no log",)),
                        (["@nested.logs"], ("nested.logs, line 1", "names another list")),
                        ([twice.name, "--columns", bench / "knee.map", "--gains-from-name", PATTERN],
                         ("matches its name more than once",))):
        p = run("fit", *args, "-o", tmp_path / "out", cwd=tmp_path, check=2)
        one_line(p, *words)
        assert not (tmp_path / "out").exists()


def test_a_validation_log_states_its_own_gains(bench, tmp_path, run):
    """--kp/--kd are the fitted logs' gains: a validation log (run at
    other gains, as it should be) that says none is refused, not replayed
    at the fitted logs' gains."""
    p = run("fit", "freq_sweep_knee_kp_5_kd_0.1.csv.gz", "--columns", "knee.map", "--kp", "5", "--kd", "0.1",
            "--validate", "freq_sweep_knee_kp_7.5_kd_0.1.csv.gz", *QUICK, "-o", tmp_path / "out", cwd=bench,
            check=2)
    one_line(p, "freq_sweep_knee_kp_7.5_kd_0.1.csv.gz: no '# kp:' line", "a --validate log runs at gains of its own",
             "::kp=K,kd=D")
    assert not (tmp_path / "out").exists()


def test_the_real_bench_logs_read_as_they_are(tmp_path, run):
    """A Pupper v3's own bench logs (gzipped, the gains in the names, no
    header): every log read through a list naming each motor's map, the
    held motors at 0; one quick fit of the knee from the command line."""
    if not REAL.is_dir():
        pytest.skip("../shared/real_logs is absent")
    from pupper_core._fit_problem import _read_logs

    motors = {3: "leg_front_l_1", 4: "leg_front_l_2", 5: "leg_front_l_3"}
    lines = []
    for idx, act in motors.items():
        (tmp_path / f"motor{idx}.map").write_text(
            f"time=time_since_fade_in (s)\n{act}.target=command (rad)\n{act}.q=motor_position (rad)\n"
            f"{act}.qd=motor_velocity (rad/s)\n")
        lines += [f"{p}::columns=motor{idx}.map" for p in sorted(REAL.glob(f"freq_sweep_motor_{idx}_*.csv.gz"))]
    (tmp_path / "bench.logs").write_text("\n".join(lines) + "\n")
    read = _read_logs([f"@{tmp_path / 'bench.logs'}"], robot(), None, {"kp": None, "kd": None, "held": "0"},
                      pattern=PATTERN)
    assert len(read) == len(lines) == 5
    for lg in read:
        idx = int(lg.path.name.split("_")[3])
        kp = 7.5 if "_kp_7.5_" in lg.path.name else 5.0
        assert lg.logged == [motors[idx]] and float(lg.kd[0]) == 0.25, lg.path.name
        assert all(float(k) == kp for k in lg.kp) and 4900 < len(lg.times) < 5400 and lg.duration > 19
    knee = next(REAL.glob("freq_sweep_motor_5_*_kp_5_kd_0.25.csv.gz"))
    p = run("fit", f"{knee}::columns=motor5.map", "--gains-from-name", PATTERN, "--held", "0",
            "--params", "kp_scale", "--max-iters", "1", "-o", tmp_path / "fit", cwd=tmp_path, check=0)
    assert "mean over 1 joint" in p.stdout and "leg_front_l_3" in (tmp_path / "fit" / "fit.csv").read_text()


# -- trust, round 4 (issue 49) ----------------------------------------------------------------


def test_item_09_same_log_other_bytes_is_one_log(short, tmp_path, run):
    """The same samples in other bytes (a BOM and CRLF line ends, gzip)
    are one log: by content after parsing, not by the file's bytes."""
    raw = short.read_bytes()
    (tmp_path / "bom_crlf.csv").write_bytes(b"\xef\xbb\xbf" + raw.replace(b"\n", b"\r\n"))
    (tmp_path / "short.csv.gz").write_bytes(gzip.compress(raw))
    for twin in ("bom_crlf.csv", "short.csv.gz"):
        p = run("fit", short, tmp_path / twin, *QUICK, "-o", tmp_path / "out", check=2)
        one_line(p, f"{twin} has the same content as", "short.csv", "the same samples in other bytes",
                 "give each log once")
        p = run("fit", short, "--validate", tmp_path / twin, *QUICK, "-o", tmp_path / "out", check=2)
        one_line(p, f"--validate {tmp_path / twin} has the same content as the fitted log")
        assert not (tmp_path / "out").exists()


def test_item_10_a_gain_given_twice_is_never_ignored(short, tmp_path, run):
    """`--kp 7` on a log whose header says `# kp: 5` is refused, naming
    both; the same value is no conflict. A validation log keeps its own
    header's gains (the fitted logs' --kp is not its)."""
    p = run("fit", short, "--kp", "7", *QUICK, "-o", tmp_path / "out", check=2)
    one_line(p, "short.csv, line 5: '# kp: 5.0' and --kp 7 disagree", "drop one, or fix the other")
    p = run("fit", f"{short}::kd=0.3", *QUICK, "-o", tmp_path / "out", check=2)
    one_line(p, "'# kd: 0.1' and", "::kd=0.3 disagree")
    assert not (tmp_path / "out").exists()
    run("fit", short, "--kp", "5", "--kd", "0.1", *QUICK, "-o", tmp_path / "same", check=0)
    from pupper_core._fit_problem import _read_logs

    text = short.read_text().replace("# kp: 5.0", "# kp: 7.5")
    (tmp_path / "kp75.csv").write_text(text)
    held_out = _read_logs([tmp_path / "kp75.csv"], robot(), None, {"kp": "5", "kd": None, "held": None},
                          role="validate")
    assert float(held_out[0].kp[0]) == 7.5


def test_item_12_held_past_the_joints_range_is_one_line(short, tmp_path, run):
    """`--held 100` (rad) was an internal error deep in the replay."""
    p = run("fit", short, "--held", "100", *QUICK, "-o", tmp_path / "out", check=2)
    one_line(p, "--held 100", "outside leg_front_r_1's range", "inside its range")
    assert not (tmp_path / "out").exists()
    with pytest.raises(pc.ConfigError, match=r"the held angle 100 rad is outside leg_front_r_1's range"):
        pc.fit(short, held=100, params="delay", max_iters=1, progress=False)
    # inside the range it runs
    pc.fit(short, held=0, params="delay", max_iters=1, progress=False)


def test_item_15_excite_checks_its_seed_before_any_work(tmp_path, monkeypatch):
    """`pc.excite(seed=-1)` raised NumPy's ValueError from inside the work."""
    import pupper_core._fit_excite as fe

    def no_work(*a, **k):
        raise AssertionError("excite started work before checking its seed")

    monkeypatch.setattr(fe, "load_robot", no_work)
    for seed in (-1, 2**64, 1.5, True, "3"):
        with pytest.raises(pc.ConfigError) as e:
            pc.excite(out=tmp_path / "x.csv", seed=seed)
        assert isinstance(e.value, ValueError) and "--seed" in str(e.value) and "whole number" in str(e.value)
    assert not (tmp_path / "x.csv").exists()


def test_item_22_excite_refuses_a_rate_fit_cannot_read(tmp_path, run):
    """`excite --rate 1` wrote a log fit then refused; it is refused up
    front with the reason, and the rate it advises is one fit reads."""
    p = run("excite", "--rate", "1", "-o", tmp_path / "x.csv", check=2)
    one_line(p, "--rate 1 Hz is too slow for fit", "swings at 8.35 Hz", "below twice that (16.7 Hz)",
             "give --rate 100 or more")
    p = run("excite", "--rate", "20", "--band", "0.3,15", "--kp", "0.5", "-o", tmp_path / "x.csv", check=2)
    one_line(p, "--band reaches 15 Hz", "(30 Hz)")
    assert not (tmp_path / "x.csv").exists()
    run("excite", "--rate", "100", "--joints", MOTOR, "--seconds", "0.6", "--hold", "0.2", "-o",
        tmp_path / "ok.csv", check=0)
    res = pc.fit(tmp_path / "ok.csv", params="delay", max_iters=1, progress=False)
    assert res.actuators == [MOTOR]


def test_item_23_fit_says_what_is_wrong_with_a_file(short, tmp_path, run):
    """An empty file, one Latin-1 byte, one 1e300 sample: each said for
    what it is (not "starts with 'nothing'", "binary", "looks like
    degrees"); a Latin-1 byte in a comment line is no obstacle."""
    lines = short.read_bytes().split(b"\n")
    row = next(i for i, ln in enumerate(lines) if ln.startswith(b"time,")) + 5

    def with_cell(col: int, value: bytes) -> bytes:
        out = list(lines)
        cells = out[row].split(b",")
        cells[col] = value
        out[row] = b",".join(cells)
        return b"\n".join(out)

    note = list(lines)
    note[1] += b" (caf\xe9 bench)"
    cases = {
        "empty.csv": (b"", ("empty.csv is empty (0 bytes)",)),
        "latin1.csv": (with_cell(2, lines[row].split(b",")[2] + b"\xe9"),
                       (f"latin1.csv, column '{MOTOR}.q', row {row + 1}", "is not a number", "fix or drop the row")),
        "huge.csv": (with_cell(2, b"1e300"),
                     (f"huge.csv, column '{MOTOR}.q', row {row + 1}: 1e+300 is no angle", "fix or drop the row")),
        "fast.csv": (with_cell(3, b"1e300"), (f"column '{MOTOR}.qd', row {row + 1}", "past what any servo gives")),
    }
    for name, (data, words) in cases.items():
        (tmp_path / name).write_bytes(data)
        p = run("fit", tmp_path / name, *QUICK, "-o", tmp_path / "out", check=2)
        line = one_line(p, *words)
        assert "binary" not in line and "look like degrees" not in line and "'nothing'" not in line, line
        assert not (tmp_path / "out").exists()
    (tmp_path / "note.csv").write_bytes(b"\n".join(note))
    run("fit", tmp_path / "note.csv", *QUICK, "-o", tmp_path / "ok", check=0)


def test_item_24_python_takes_numpy_numbers_one_path_and_gains_per_joint(short, tmp_path, monkeypatch):
    """NumPy scalars are numbers, band "F0,F1" is the CLI's text, out=None
    is the default file, validate="x.csv" is one path (not its
    characters), kp=[5, 5] is one gain per logged joint."""
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        two = Path(pc.excite(out=None, seconds=np.float32(0.5), hold=np.float64(0.2), rate=np.int64(250),
                             band="0.5,4", seed=np.int64(2), joints=[MOTOR, "leg_front_l_3"],
                             amplitude=np.float32(0.2)))
    assert two == Path("excite.csv") and (tmp_path / "excite.csv").is_file()
    assert "0.5-4 Hz" in two.read_text().splitlines()[1]
    for band in ("0.5", "a,b", (1.0,)):
        with pytest.raises(pc.ConfigError, match=r"--band .* is not two numbers F0,F1 \(Hz\)"):
            pc.excite(out="no.csv", band=band)
    assert not Path("no.csv").exists()
    res = pc.fit(short, validate=str(two), params="delay", max_iters=1, progress=False)
    assert [r["log"] for r in res.validation] == ["excite.csv", "excite.csv"]
    bare = without_gains(two, tmp_path / "bare.csv")
    res = pc.fit(bare, kp=[5, 5], kd=np.float32(0.1), params="delay", max_iters=1, progress=False)
    assert res.actuators == [MOTOR, "leg_front_l_3"]
    res = pc.fit({bare: {"kp": np.array([5.0, 5.0]), "kd": 0.1}}, params="delay", max_iters=1, progress=False)
    assert res.actuators == [MOTOR, "leg_front_l_3"]
    with pytest.raises(pc.ConfigError, match=r"must be one gain, or one per logged actuator \(2\)"):
        pc.fit(bare, kp=[5, 5, 5], kd=0.1, progress=False)
    with pytest.raises(pc.ConfigError, match=r"kp=\[5, 'x'\] is not a number or one per logged joint"):
        pc.fit(bare, kp=[5, "x"], kd=0.1, progress=False)
    assert math.isfinite(res.value("delay"))


def test_the_troubleshooting_rows_for_logs_are_what_fit_says(tmp_path, run, pupper_bin):
    """docs/troubleshooting.md's fit rows that need a file set up (said in
    words): each set up here and run; the page shows exactly what fit says."""
    from test_docs import ERROR_ROW

    base = tmp_path / "base"
    base.mkdir()
    run("excite", "--joints", MOTOR, "--rate", "250", "--seconds", "1", "--hold", "0.2", "-o", base / "run.csv",
        check=0)
    run("excite", "--joints", MOTOR, "--rate", "250", "--seconds", "1", "--hold", "0.2", "--seed", "1", "-o",
        base / "other.csv", check=0)
    log = (base / "run.csv").read_bytes()

    def huge() -> bytes:
        lines = log.split(b"\n")
        row = next(i for i, ln in enumerate(lines) if ln.startswith(b"time,")) + 5
        cells = lines[row].split(b",")
        cells[2] = b"1e300"
        lines[row] = b",".join(cells)
        return b"\n".join(lines)

    setups = {
        "its header says # kp: 5.0": {"run.csv": log},
        "a log of one knee": {"run.csv": log},
        "run.csv gzipped": {"run.csv": log, "run.csv.gz": gzip.compress(log)},
        "b.csv says no gains": {"run.csv": log, "b.csv": b"".join(
            ln for ln in (base / "other.csv").read_bytes().splitlines(keepends=True)
            if not ln.startswith((b"# kp:", b"# kd:")))},
        "an empty file": {"empty.csv": b""},
        "zstd-compressed": {"run.csv.zst": b"\x28\xb5\x2f\xfd" + log[:100]},
        "a gzip cut short": {"cut.csv.gz": gzip.compress(log)[:2000]},
        "1e300 in an angle column": {"run.csv": huge()},
    }
    env = clean_env(PATH=f"{pupper_bin.parent}{os.pathsep}{os.environ['PATH']}")
    text = (REPO / "docs" / "troubleshooting.md").read_text()
    rows = [(m.group(1), m.group(2)) for line in text.splitlines() if (m := ERROR_ROW.match(line))
            and m.group(1).startswith(("pupper fit", "pupper excite")) and "  (" in m.group(1)]
    assert len(rows) == len(setups), rows
    for i, (cell, message) in enumerate(rows):
        cmd, _, note = cell.partition("  (")
        where = tmp_path / f"row{i}"
        where.mkdir()
        for name, data in setups[note.rstrip(")")].items():
            (where / name).write_bytes(data)
        p = subprocess.run(cmd, shell=True, cwd=where, capture_output=True, text=True, timeout=240, env=env)
        assert p.returncode == 2 and p.stderr.strip() == message, (cmd, p.stderr)
        assert not (where / "runs").exists()
