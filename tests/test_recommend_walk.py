"""`pupper recommend --task walk`: gains ranked by how the drawn robots walk
(`pupper walk`'s speed error at the gait), under recommend's own margins
and constraints, set beside `--task stand`'s pick with why they differ.

Real MuJoCo on the built-in model (one quick search, the command
docs/recommend.md shows) and on tests/models/trotter15.xml (its own gains
and torque limits, scored by walking):

    pupper recommend --task walk --trials 4 --batch 4 --robots 4 --polish 2 --seconds 5 -q -o runs/rec_walk
"""

from __future__ import annotations

import csv
import json
import re
import shlex
import subprocess
from pathlib import Path

import pytest

from conftest import REPO, assert_refused, clean_env, read_csv

pytest.importorskip("optuna")

DOC_COMMAND = shlex.split(next(line for line in __doc__.splitlines()
                               if line.strip().startswith("pupper recommend --task walk")))


@pytest.fixture(scope="module")
def walk_run(pupper_bin, tmp_path_factory):
    cwd = tmp_path_factory.mktemp("recwalk")
    p = subprocess.run([str(pupper_bin), *DOC_COMMAND[1:]], capture_output=True, text=True, cwd=cwd,
                       env=clean_env(), timeout=1200)
    assert p.returncode == 0, p.stderr[-3000:]
    return cwd / DOC_COMMAND[-1], p


def test_the_walk_pick_keeps_the_margins_and_walks_best_of_what_held(walk_run):
    d, p = walk_run
    assert p.stdout.startswith("recommended gains for a trot at 2 Hz and 0.25 m/s, holding on each of 4 drawn "
                               "robots: none fell")
    with open(d / "recommend.csv", newline="") as f:
        cards = list(csv.DictReader(f))
    assert [c["group"] for c in cards] == ["hfe", "haa", "kfe"]
    for c in cards:
        # recommend's loop margins and torque headroom, as --task stand keeps them
        assert float(c["phase_margin_deg"]) >= 30 - 1e-9 and float(c["gain_margin_db"]) >= 6 - 1e-9
        assert 0 < float(c["torque_headroom_pct"]) < 100
        assert c["task"] == "walk" and c["gait"] == "trot"
    _, trials = read_csv(d / "trials.csv")
    ok = [t for t in trials if t["status"] == "ok"]
    assert ok and all(int(t["robots"]) == 4 and int(t["fell"]) == 0 for t in ok)
    assert all(float(t["max_tilt_rms_deg"]) <= 10 for t in ok)
    # the rule: the lowest p95 speed error among those that held (2 % ties)
    low = min(float(t["p95_speed_error_pct"]) for t in ok)
    m = json.loads((d / "manifest.json").read_text())
    picked = [t for t in ok if all(float(t[f"{k}.{g}"]) == v[k] for g, v in m["pick"].items() for k in ("kp", "kd"))]
    assert picked and float(picked[0]["p95_speed_error_pct"]) <= low * 1.02
    assert m["inputs"]["task"] == "walk" and m["inputs"]["seconds"] == 5


def test_the_card_says_how_the_pick_differs_from_the_stands_and_why(walk_run):
    d, p = walk_run
    m = json.loads((d / "manifest.json").read_text())
    stand = m["stand_pick"]
    # --task stand's pick: the stiffest gains the margins allow (its card in docs/recommend.md)
    assert stand["gains"]["hfe"] == {"kp": 26.86, "kd": 0.4346}
    assert stand["gains"] != m["pick"]
    # each scored on the other's task: the stand pick walks worse, the walk pick dips more
    assert m["p95_speed_error_pct"] < stand["walking"]["p95_speed_error_pct"]
    assert stand["p95_push_dip_mm"] < m["pick_standing"]["p95_push_dip_mm"]
    out = p.stdout
    assert "against --task stand's pick" in out and "\n  why: the walk ranks the speed" in out
    assert re.search(r"bandwidth: every group of this pick keeps its natural frequency sqrt\(kp/J\) at [\d.]+×", out)
    assert m["compared"] == out[out.index("against --task stand's pick"):].splitlines()[:len(m["compared"])]


def test_the_exported_model_walks_the_cards_numbers_again(walk_run, run):
    d, _ = walk_run
    m = json.loads((d / "manifest.json").read_text())
    args = shlex.split(m["reproduce"])
    assert args[:2] == ["pupper", "walk"]
    # its paths are the recommend's own, from the directory it ran in
    run(*args[1:], "-q", "-o", d / "again", cwd=d.parent.parent, check=0)
    _, rows = read_csv(d / "again" / "summary.csv")
    with open(d / "recommend.csv", newline="") as f:
        card = next(csv.DictReader(f))
    assert float(rows[0]["p95:speed_error_pct"]) == pytest.approx(float(card["p95_speed_error_pct"]), rel=1e-9)


def test_the_docs_show_what_the_walk_answer_prints(walk_run):
    _, p = walk_run
    page = (REPO / "docs" / "recommend.md").read_text()
    assert shlex.join(DOC_COMMAND) in page
    start = page.index("recommended gains for a trot")
    shown = page[start:page.index("```", start)]
    norm = lambda s: [" ".join(line.split()) for line in s.strip().splitlines()]  # noqa: E731
    assert norm(shown) == norm(p.stdout), "regenerate docs/recommend.md's --task walk block from the run"


def test_a_third_party_quadruped_is_scored_walking_on_its_own_gains_and_limits():
    from pupper_core._recommend import plan_for
    from pupper_core._recommend.search import Candidate, simulate

    p = plan_for(str(REPO / "tests" / "models" / "trotter15.xml"), task="walk", robots=2, seconds=5)
    # its own kp 50 / kv 0.5, +-24 N.m and 0.27 m stance: the searched ranges, limits and sag are the model's
    for g in p.groups:
        assert g.kp_range == pytest.approx((5, 1000)) and g.kd_range == pytest.approx((0.05, 25))
        assert g.torque_limit == 24
    assert p.stance == pytest.approx(0.27, abs=2e-3)
    own, stiffer, tenth = (Candidate({g.name: gains for g in p.groups}) for gains in ((50.0, 0.5), (150.0, 1.5),
                                                                                        (5.0, 0.5)))
    simulate(p, [own, stiffer, tenth], [p.model], lambda _: None)
    for c in (own, stiffer):
        # both walk on every robot, within the motors' torque
        assert c.robots == 2 and c.fell == 0 and c.figures["p5_speed_ms"] > 0.05, c
        assert c.score == c.figures["p95_speed_error_pct"] and c.p95_peak_torque <= 24 + 1e-9
    # on 15 kg its own kp 50 crouches while it walks (judged against its own stance), and
    # three times that walks closer to the commanded speed
    assert own.failed.startswith("sags to") and "of its 270.0 mm stance" in own.failed
    assert stiffer.score < own.score
    # a tenth of its gains does not carry it
    assert tenth.fell == 2


@pytest.mark.parametrize(("args", "words"), [
    (("--gait", "trot"), "--gait sets the walk the gains are ranked on: add --task walk"),
    (("--task", "run"), "--task 'run' is not a task: use stand (a push) or walk (a gait)"),
    (("--task", "walk", "--push-force", "20"), "--push-force is the stand task's push"),
    (("--task", "walk", "--speed", "0"), "--speed 0.0 is no speed to walk at"),
    (("--task", "walk", "--gait", "gallop"), "unknown gait 'gallop'"),
    (("--task", "walk", "--seconds", "3"), "leaves no whole gait cycle of steady walking"),
])
def test_bad_input_is_one_line_and_no_run_directory(run, tmp_path, args, words):
    out = tmp_path / "bad"
    assert_refused(run("recommend", *args, "-o", out), words, out)
