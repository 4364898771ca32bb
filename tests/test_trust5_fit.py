"""Trust, round 5 (issue 61), the fit's items: a fit run is checked before
it is believed (items 4 and 5), and what tells a feedback latency from a
command delay is said right (item 11, in tests/test_fit_logs.py's
test_one_kp_cannot_tell_the_latency_from_the_delay_and_says_so)."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

pytest.importorskip("scipy", reason="the fit extra (make test installs it)")
pytest.importorskip("optuna", reason="the tune extra (make test installs it)")


@pytest.fixture(scope="module")
def fit_run(tmp_path_factory, pupper_bin) -> Path:
    """A quick real fit: the knees' excitation, armature, damping and the kp scale."""
    import subprocess

    from conftest import clean_env

    d = tmp_path_factory.mktemp("trust5fit")
    for args in (["excite", "--seconds", "1.5", "--hold", "0.3", "-o", d / "ex.csv"],
                 ["fit", d / "ex.csv", "--params", "armature,damping,kp_scale,delay", "--max-iters", "5",
                  "-o", d / "fit"]):
        p = subprocess.run([str(pupper_bin), *map(str, args)], capture_output=True, text=True, env=clean_env(),
                           cwd=d, timeout=600)
        assert p.returncode == 0, p.stderr
    return d / "fit"


def _edited(fit_run: Path, tmp_path: Path, edit) -> Path:
    d = tmp_path / "edited"
    shutil.copytree(fit_run, d)
    edit(d)
    return d


def _rows(d: Path) -> list[dict[str, str]]:
    with open(d / "fit.csv", newline="") as f:
        return list(csv.DictReader(f))


def _write_rows(d: Path, rows: list[dict[str, str]]) -> None:
    with open(d / "fit.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


@pytest.mark.parametrize("what, value", [("delay", "10"), ("kp_scale", "nan"), ("armature", "-0.01")])
def test_item_4_an_edited_fit_csv_is_refused_in_one_line(fit_run, tmp_path, run, what, value):
    """A 10 s delay, a NaN kp scale, a negative armature typed into
    fit.csv: refused before any robot runs, naming the run and the fix."""
    def edit(d: Path) -> None:
        rows = _rows(d)
        for r in rows:
            if r["parameter"].startswith(what):
                r["fitted"] = value
        _write_rows(d, rows)

    d = _edited(fit_run, tmp_path, edit)
    for args in (["recommend", "--from-fit", d, "--robots", "8", "--trials", "2", "-q", "-o", tmp_path / "rec"],
                 ["gains", "--from-fit", d, "--kp", "5", "--kd", "0.25"]):
        p = run(*args, check=2)
        assert len(p.stderr.strip().splitlines()) == 1 and str(d) in p.stderr, p.stderr
        assert "fit.csv" in p.stderr and "run `pupper fit` again" in p.stderr, p.stderr
    assert not (tmp_path / "rec").exists()


def test_item_4_even_without_the_manifests_hashes_a_value_outside_its_bounds_is_refused(fit_run, tmp_path, run):
    """A run made before the fit recorded its files' hashes is read as it
    is: its values are still checked against what a fit gives."""
    def edit(d: Path) -> None:
        m = json.loads((d / "manifest.json").read_text())
        del m["outputs"]
        (d / "manifest.json").write_text(json.dumps(m))
        rows = _rows(d)
        for r in rows:
            if r["parameter"] == "delay":
                r["fitted"] = "10"
        _write_rows(d, rows)

    d = _edited(fit_run, tmp_path, edit)
    p = run("recommend", "--from-fit", d, "--robots", "8", "--trials", "2", "-q", "-o", tmp_path / "rec", check=2)
    assert "fit.csv's delay is 10 s, outside the 0 to 0.05 a fit gives it" in p.stderr, p.stderr


def test_item_5_a_calibrated_model_that_is_not_the_fits_is_refused(fit_run, tmp_path, run):
    """calibrated.xml swapped or edited after the fit: its SHA-256 is not
    the manifest's, and the answer would change with no word."""
    d = _edited(fit_run, tmp_path, lambda d: (d / "calibrated.xml").write_text(
        (d / "calibrated.xml").read_text().replace('armature="', 'armature="1')))
    p = run("gains", "--from-fit", d, "--kp", "5", "--kd", "0.25", check=2)
    assert "calibrated.xml is not the file the fit wrote" in p.stderr, p.stderr


def test_item_5_another_kinds_run_is_not_a_fit(fit_run, tmp_path, run):
    def edit(d: Path) -> None:
        m = json.loads((d / "manifest.json").read_text())
        m["kind"] = "sweep"
        (d / "manifest.json").write_text(json.dumps(m))

    d = _edited(fit_run, tmp_path, edit)
    p = run("recommend", "--from-fit", d, "--robots", "8", "-q", "-o", tmp_path / "rec", check=2)
    assert "its manifest is a sweep run's, not a fit's" in p.stderr, p.stderr
