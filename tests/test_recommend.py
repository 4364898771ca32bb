"""`pupper recommend`: gains per joint group that hold on every drawn robot.

The margins are re-checked here from the model with this file's own
linearisation (the joint-space inertia from MuJoCo at the stand pose, the
loop L = (kp + kd s e^{-s d}) e^{-s tau} / (J s^2) scanned in frequency),
at the spread's corners; the exports are loaded with a YAML parser and
MuJoCo, and the card's push dip is reproduced by the sweep the manifest
names. The run most tests read is docs/recommend.md's example:

    pupper recommend --trials 8 --batch 8 --robots 32 --polish 1 -q -o runs/rec
"""

from __future__ import annotations

import csv
import json
import shlex
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

from conftest import stamp_of

pytest.importorskip("optuna")

# a quick search: the Done-when's 32 robots per candidate, fewer candidates
QUICK = ("--trials", "8", "--batch", "8", "--robots", "32", "--polish", "1")
DOC_COMMAND = shlex.split(next(line for line in __doc__.splitlines() if line.strip().startswith("pupper recommend --")))


def cards(d: Path) -> dict[str, dict[str, str]]:
    with open(d / "recommend.csv", newline="") as f:
        return {r["group"]: r for r in csv.DictReader(f)}


@pytest.fixture(scope="module")
def default_run(pupper_bin, tmp_path_factory):
    import subprocess

    from conftest import clean_env

    cwd = tmp_path_factory.mktemp("rec")
    assert DOC_COMMAND[1:-2] == ["recommend", *QUICK, "-q"]
    p = subprocess.run([str(pupper_bin), *DOC_COMMAND[1:]], capture_output=True, text=True, cwd=cwd,
                       env=clean_env(), timeout=1200)
    assert p.returncode == 0, p.stderr[-3000:]
    return cwd / DOC_COMMAND[-1], p


def reflected_inertia(model: str = "pupper_v3") -> dict[str, float]:
    """Each actuator's joint-space inertia diagonal (armature included) on
    the robot hung in the air at the stand pose, from MuJoCo directly."""
    import pupper_core as pc

    m = mujoco.MjModel.from_xml_path(str(Path(pc.__file__).parent / "models" / model / "scene.xml"))
    d = mujoco.MjData(m)
    stand = pc.pose(model)["targets"]
    for a, q in enumerate(stand):
        d.qpos[m.jnt_qposadr[m.actuator_trnid[a, 0]]] = q
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)  # mujoco 4: reads d's sparse inertia itself
    # hung in the air: the base is welded, so the legs' own block
    legs = [m.jnt_dofadr[m.actuator_trnid[a, 0]] for a in range(m.nu)]
    return {m.actuator(a).name: float(full[legs[a], legs[a]]) for a in range(m.nu)}


def phase_margin(inertia: float, kp: float, kd: float, latency: float, d_delay: float) -> float:
    """180° + arg L at |L| = 1: 1/(J s²) turns by -180°, the latency by -w·tau,
    the PD (its real part positive) by its own angle."""
    w = np.logspace(-1, 5, 400001)
    ctrl = kp + kd * 1j * w * np.exp(-1j * w * d_delay)
    k = int(np.argmax(np.abs(ctrl) / (inertia * w**2) <= 1.0))
    return float(np.degrees(np.angle(ctrl[k]) - w[k] * latency))


def worst_margin(inertia: float, kp: float, kd: float, latency: float, d_delay: float) -> float:
    # every robot: motor gains ±10 %, leg inertia ±10 % (the spread the card holds on)
    return min(phase_margin(inertia * fi, kp * fg, kd * fg, latency, d_delay)
               for fg in (0.9, 1.0, 1.1) for fi in (0.9, 1.0, 1.1))


def test_the_card_holds_every_constraint_on_every_robot(default_run):
    d, p = default_run
    c = cards(d)
    assert set(c) == {"haa", "hfe", "kfe"}
    assert "recommended gains, holding on each of 32 drawn robots" in p.stdout
    # the loop as rate=500,counts=16384 closes it, 2 ms of sensing delay:
    # latency 2 ms + 1 ms, the derivative 1 ms more
    inertia = reflected_inertia()
    groups = json.loads((d / "manifest.json").read_text())["inputs"]["ranges"]
    stamp_of(d, "recommend")
    assert set(groups) == set(c)
    import pupper_core as pc

    by_group = {j["actuator"]: j["group"] for j in pc.gains(kp=5, kd=0.1)["joints"]}
    for act, J in inertia.items():
        g = c[by_group[act]]
        pm = worst_margin(J, float(g["kp"]), float(g["kd"]), 0.003, 0.001)
        assert pm >= 30 - 0.5, (act, g["kp"], g["kd"], pm)
    # every candidate that ranked: no robot fell, none saturated past 5 %
    with open(d / "trials.csv", newline="") as f:
        ok = [r for r in csv.DictReader(f) if r["status"] == "ok"]
    assert ok and all(r["fell"] == "0" and float(r["max_saturation"]) < 0.05 for r in ok)
    assert all(int(r["robots"]) == 32 for r in ok)
    # the pick is one of them, at the digits the exports carry
    pick = [r for r in ok if all(float(r[f"kp.{g}"]) == float(c[g]["kp"]) and float(r[f"kd.{g}"]) == float(c[g]["kd"])
                                  for g in c)]
    # the card's dip is the exported MJCF's (written to six digits): the search's within 1 %
    assert pick and float(pick[0]["p95_push_dip_mm"]) == pytest.approx(float(c["kfe"]["p95_push_dip_mm"]), rel=0.01)


def stance_height(model: str = "pupper_v3") -> float:
    """The base height with the lowest foot sphere on the floor at the
    model's keyframe, from MuJoCo directly."""
    import pupper_core as pc

    m = mujoco.MjModel.from_xml_path(str(Path(pc.__file__).parent / "models" / model / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_kinematics(m, d)
    feet = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
            and (m.geom_contype[g] or m.geom_conaffinity[g])]
    assert len(feet) == 4
    return float(d.qpos[2] - min(d.geom_xpos[g][2] - m.geom_size[g][0] for g in feet))


def test_no_ranked_candidate_sags_and_the_tradeoff_set_is_undominated(default_run):
    d, p = default_run
    stance = stance_height()
    m = json.loads((d / "manifest.json").read_text())
    assert m["inputs"]["stance_m"] == pytest.approx(stance, rel=1e-9) and m["inputs"]["max_sag"] == 0.1
    assert f"none ends more than 10 % below its {1000 * stance:.1f} mm stance height" in p.stdout
    with open(d / "trials.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    ok = [r for r in rows if r["status"] == "ok"]
    # every ranked candidate's lowest robot stands within 10 % of the stance;
    # a candidate refused for sagging is said so with its height
    assert ok and all(float(r["min_height_m"]) >= 0.9 * stance for r in ok)
    for r in rows:
        if r["status"].startswith("sags to"):
            assert float(r["min_height_m"]) < 0.9 * stance and r["fell"] == "0"
    # the trade-off set, checked from trials.csv: no ranked candidate is at
    # least as good on dip, slowest group's frequency and height, and better on one
    inertia = {g: hi for g, (_, hi) in m["inputs"]["inertia"].items()}

    def keys(r: dict[str, str]) -> tuple[float, float, float]:
        hz = min(np.sqrt(float(r[f"kp.{g}"]) / inertia[g]) for g in inertia) / (2 * np.pi)
        return float(r["p95_push_dip_mm"]), -hz, -float(r["min_height_m"])

    with open(d / "tradeoffs.csv", newline="") as f:
        front = list(csv.DictReader(f))
    assert front
    every = [keys(r) for r in ok]
    for r in front:
        k = keys(r)
        assert float(r["slowest_hz"]) == pytest.approx(-k[1], rel=1e-12)
        assert not any(all(a <= b for a, b in zip(o, k)) and o != k for o in every), r["trial"]
    in_front = {r["trial"] for r in front}
    for r, k in zip(ok, every):
        if r["trial"] not in in_front:
            assert any(all(a <= b for a, b in zip(keys(f), k)) for f in front), r["trial"]
    page = (d / "report.html").read_text()
    assert "Trade-off set" in page or len(front) == 1
    # the figure: a dot per ranked candidate (the pick a star, drawn once)
    figure = page.split('aria-label="candidates that held every constraint', 1)[1].split("</svg>", 1)[0]
    assert figure.count("data-id=") == len(ok) and figure.count("<circle") == len(ok) - 1


def test_a_crouch_that_barely_dips_is_refused():
    # gains that leave the robot standing 19 % low: no fall, a small dip, no answer
    from pupper_core._recommend import plan_for as make_plan
    from pupper_core._recommend.search import Candidate, simulate

    plan = make_plan(robots=8)
    crouch = Candidate({"hfe": (2.104, 0.5014), "haa": (0.8152, 0.1214), "kfe": (3.362, 0.2498)})
    simulate(plan, [crouch], [plan.model], lambda s: None)
    assert crouch.fell == 0 and crouch.robots == 8
    assert crouch.min_height_m < 0.9 * stance_height()
    assert crouch.failed.startswith(f"sags to {1000 * crouch.min_height_m:.1f} mm on its lowest robot"), crouch.failed
    # and with room for it (--max-sag 0.3) the same robots rank it
    loose = make_plan(robots=8, max_sag=0.3)
    again = Candidate(dict(crouch.gains))
    simulate(loose, [again], [loose.model], lambda s: None)
    assert again.feasible and again.min_height_m == crouch.min_height_m


def test_the_docs_show_what_the_quick_answer_prints(default_run):
    # docs/recommend.md shows this run's output (stdout, then the files said on stderr)
    from conftest import REPO

    page = (REPO / "docs" / "recommend.md").read_text()
    shown = page.split("```text\n", 1)[1].split("```", 1)[0]
    _, p = default_run
    norm = lambda t: " ".join(t.split())  # noqa: E731
    assert norm(shown) == norm(p.stdout + p.stderr)


def test_the_stiff_corner_is_passed_over(default_run):
    import pupper_core as pc

    d, _ = default_run
    c = cards(d)
    # the nominal sweep's pick (kp 120, kd 1) has no loop margin under this
    # firmware: the card's gains are inside theirs
    stiff = pc.gains(kp=120, kd=1, motor="rate=500,counts=16384", sensing_delay=0.002)
    assert all(g["phase_margin_deg"] < 0 for g in stiff["groups"])
    assert all(float(g["phase_margin_deg"]) >= 30 and float(g["gain_margin_db"]) >= 6 for g in c.values())
    # every neighbour of the pick says why it lost
    m = json.loads((d / "manifest.json").read_text())
    assert m["kind"] == "recommend" and len(m["neighbours"]) >= 6
    assert all(": " in n for n in m["neighbours"])


def test_exports_load_and_reproduce_the_card(default_run, run):
    d, _ = default_run
    c = cards(d)
    doc = yaml.safe_load((d / "recommended.yaml").read_text())
    params = doc["neural_controller"]["ros__parameters"]
    import pupper_core as pc

    names = [a["name"] for a in pc.info()["actuators"]]
    by_group = {j["actuator"]: j["group"] for j in pc.gains(kp=5, kd=0.1)["joints"]}
    assert params["joint_names"] == names and len(params["kps"]) == len(params["kds"]) == 12
    for n, kp, kd in zip(names, params["kps"], params["kds"]):
        assert (kp, kd) == (float(c[by_group[n]]["kp"]), float(c[by_group[n]]["kd"]))
    m = mujoco.MjModel.from_xml_path(str(d / "recommended.xml"))
    for a, n in enumerate(names):
        assert m.actuator_gainprm[a, 0] == params["kps"][a]
        assert (m.actuator_biasprm[a, 1], m.actuator_biasprm[a, 2]) == (-params["kps"][a], -params["kds"][a])
    # a sweep on the MJCF at its own gains gives the card's p95 push dip
    cmd = shlex.split(json.loads((d / "manifest.json").read_text())["reproduce"])
    assert cmd[:2] == ["pupper", "sweep"]
    out = d.parent / "again"
    run(*cmd[1:], "-q", "-o", out, cwd=d.parent.parent, check=0)  # where recommend ran
    with open(out / "replicates.csv", newline="") as f:
        dips = [float(r["push_dip_mm"]) for r in csv.DictReader(f)]
    assert len(dips) == 32
    assert float(np.percentile(dips, 95)) == pytest.approx(float(c["kfe"]["p95_push_dip_mm"]), rel=1e-12)


def test_joint_order_and_controller_name_the_yaml(run, tmp_path):
    import pupper_core as pc

    names = [a["name"] for a in pc.info()["actuators"]]
    order = names[::-1]
    p = run("recommend", "--trials", "4", "--batch", "4", "--robots", "8", "--polish", "0",
            "--joint-order", ",".join(order),
            "--controller", "my_ctrl", "-q", "-o", tmp_path / "r", check=0)
    doc = yaml.safe_load((tmp_path / "r" / "recommended.yaml").read_text())["my_ctrl"]["ros__parameters"]
    assert doc["joint_names"] == order
    c = cards(tmp_path / "r")
    by_group = {j["actuator"]: j["group"] for j in pc.gains(kp=5, kd=0.1)["joints"]}
    assert doc["kps"] == [float(c[by_group[n]]["kp"]) for n in order]
    assert "report.html" in p.stderr


@pytest.mark.parametrize("args, says", [
    (("--robots", "0"), "robots 0"),
    (("--joint-order", "leg_front_r_1,elbow"), "'elbow'"),
    (("--min-phase-margin", "-5"), "--min-phase-margin"),
    (("--max-sag", "1.5"), "--max-sag"),
    (("--motor", "rate=-3"), "rate"),
    (("--command-delay", "0.01", "--motor", "rate=500,delay=0.01"), "keep one"),
])
def test_bad_input_is_one_line_and_no_run_directory(run, tmp_path, args, says):
    p = run("recommend", *args, "-o", tmp_path / "r", check=2)
    assert says in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert not (tmp_path / "r").exists()


def test_without_optuna_it_says_the_extra(run, tmp_path):
    from conftest import hidden

    p = run("recommend", "-o", tmp_path / "r", env=hidden(tmp_path, "optuna"), check=2)
    assert "PUPPER_EXTRAS=tune" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("latency", [("--sensing-delay", "0.004"), ("--motor", "rate=250,counts=16384")],
                         ids=["sensing-delay", "slower-firmware"])
def test_more_latency_in_the_loop_lowers_kd(run, tmp_path, default_run, latency):
    # 4 ms old measurements, or half the update rate (a period more in the loop):
    # less derivative gain in every group, the margins still held
    base = cards(default_run[0])
    run("recommend", *QUICK, *latency, "-q", "-o", tmp_path / "r", check=0)
    s = cards(tmp_path / "r")
    assert all(float(s[g]["kd"]) < float(base[g]["kd"]) for g in base)
    assert all(float(s[g]["phase_margin_deg"]) >= 30 and float(s[g]["gain_margin_db"]) >= 6 for g in s)


def test_a_command_delay_shifts_the_step_not_the_gains(default_run):
    # what picks the gains does not see a command delay: the loop margins
    # (the search's windows) are the same, and the push never moves the
    # target, so the pick's robots dip and hold alike; its step response has
    # the same shape, only later (the whole search is not run twice: these
    # are what it reads)
    from pupper_core._recommend import plan_for
    from pupper_core._recommend.card import _step_response
    from pupper_core._recommend.search import Candidate, simulate, windows

    d, _ = default_run
    base = cards(d)
    now, late = plan_for(robots=8), plan_for(robots=8, command_delay=0.01)
    assert now.motor != late.motor  # the delay is in the firmware the robots run
    w_now, w_late = windows(now), windows(late)
    assert w_now.keys() == w_late.keys() == base.keys()
    for g in w_now:
        for f in ("kps", "lo", "hi"):
            np.testing.assert_array_equal(getattr(w_now[g], f), getattr(w_late[g], f), err_msg=f"{g}.{f}")
    pick = {g: (float(c["kp"]), float(c["kd"])) for g, c in base.items()}
    ran = [Candidate(dict(pick)), Candidate(dict(pick))]
    simulate(now, ran[:1], [now.model], lambda s: None)
    simulate(late, ran[1:], [late.model], lambda s: None)
    assert ran[0].robots == ran[1].robots == 8
    assert (ran[0].p95_dip_mm, ran[0].fell, ran[0].max_saturation, ran[0].min_height_m) == (
        ran[1].p95_dip_mm, ran[1].fell, ran[1].max_saturation, ran[1].min_height_m)
    step, later = _step_response(now, d / "recommended.xml"), _step_response(late, d / "recommended.xml")
    for g in base:
        # the same step response, only later: its shape (rise, overshoot) unchanged
        assert later[g]["rise_time_s"] == pytest.approx(step[g]["rise_time_s"], rel=0.01, abs=0.002)
        assert later[g]["overshoot_pct"] == pytest.approx(step[g]["overshoot_pct"], abs=0.5)
    # and 10 ms later to settle (to the 2 ms step) where settling is crisp; a
    # slow group's last creep into the 2 % band on a quantised encoder is not
    crisp = [g for g in base if step[g]["settling_time_s"] < 0.3]
    assert crisp
    for g in crisp:
        shift = later[g]["settling_time_s"] - step[g]["settling_time_s"]
        assert abs(shift - 0.01) <= 0.0021, (g, shift)

def test_from_fit_the_robots_are_the_ones_the_fit_drew(run, tmp_path):
    """Issue 59: the robots recommend stands its candidates on are the fit's
    own (robots.csv: drawn from its joint distribution, each replayed on
    its logs), not corners of independent intervals: each robot_k.xml holds
    robot k's values, and no motor-gain spread is added on top."""
    run("excite", "--seconds", "1.5", "--hold", "0.3", "-o", tmp_path / "ex.csv", check=0)
    run("fit", tmp_path / "ex.csv", "--params", "armature,damping,kp_scale", "-o", tmp_path / "fit", check=0)
    with open(tmp_path / "fit" / "robots.csv", newline="") as f:
        robots = list(csv.DictReader(f))
    assert len(robots) == 8
    fit = json.loads((tmp_path / "fit" / "manifest.json").read_text())
    assert fit["robots"]["worst_over_fitted"] <= fit["robots"]["ratio"] * 1.05
    run("recommend", "--from-fit", tmp_path / "fit", "--robots", "8", "--trials", "4", "--batch", "4",
        "--polish", "0", "-q", "-o", tmp_path / "rec", check=None)
    m = json.loads((tmp_path / "rec" / "manifest.json").read_text())
    assert m["inputs"]["model"].endswith("calibrated.xml")
    values = m["inputs"]["fit_robots"]["values"]
    assert len(values) == 8
    names = [k for k in robots[0] if k not in ("robot", "rms_rad")]
    for k, robot in enumerate(robots):
        assert values[k] == pytest.approx([float(robot[n]) for n in names])
        model = mujoco.MjModel.from_xml_path(str(tmp_path / "rec" / "robots" / f"robot_{k}.xml"))
        knee = model.jnt_dofadr[model.actuator_trnid[model.actuator("leg_front_r_3").id, 0]]
        # MjSpec writes six significant digits
        assert model.dof_armature[knee] == pytest.approx(float(robot["armature"]), rel=1e-5)
    assert m["inputs"]["kp_factors"] == [1.0, 1.0]
    assert not any(s.startswith(("motor_gain=", "motor_delay=")) for s in m["inputs"]["spread"])


def test_a_calibrated_model_runs_its_fitted_servo(run, tmp_path):
    """Issue 59: a model that carries a fitted torque lag (calibrated.xml's
    pupper:lag numerics) runs it in torque mode, as --motor lag= runs it on
    the plain model, to the digit; its loop margins close through it; and a
    servo-mode run says in one line that it leaves it out."""
    spec = mujoco.MjSpec.from_file(str(Path(__import__("pupper_core").__file__).parent / "models" / "pupper_v3"
                                       / "scene.xml"))
    # both written by MjSpec (which rounds a model's numbers), one with the numerics
    plain_xml = tmp_path / "plain.xml"
    plain_xml.write_text(spec.to_xml())
    for a in spec.actuators:
        spec.add_numeric(name=f"pupper:lag:{a.name}", data=[0.008])
    model = tmp_path / "lagged.xml"
    model.write_text(spec.to_xml())
    args = ["response", "--mode", "torque", "--kp", "5", "--kd", "0.25", "--joints", "kfe", "-q"]
    run(*args, "--model", model, "-o", tmp_path / "own", check=0)
    run(*args, "--model", plain_xml, "--motor", "lag=0.008", "-o", tmp_path / "given", check=0)
    assert (tmp_path / "own" / "response.csv").read_text() == (tmp_path / "given" / "response.csv").read_text()
    g = json.loads(run("gains", "--model", model, "--kp", "5", "--kd", "0.25", "--json", check=0).stdout)
    plain = json.loads(run("gains", "--kp", "5", "--kd", "0.25", "--json", "--motor", "ideal", check=0).stdout)
    assert g["fitted"] and all(j["loop"]["torque_lag"] == 0.008 for j in g["joints"])
    knee = lambda r: min(j["phase_margin_deg"] for j in r["joints"] if j["group"] == "kfe")  # noqa: E731
    assert knee(g) < knee(plain) - 10
    p = run("sweep", "--model", model, "--grid", "kp=5", "--seconds", "1", "-q", "-o", tmp_path / "servo", check=0)
    assert "the model carries a calibrated servo (torque lag up to 8 ms" in p.stderr and "--mode torque runs them" in p.stderr


def test_sigterm_stops_it_in_one_line_keeping_what_ran(pupper_bin, tmp_path):
    import signal
    import subprocess
    import time

    from conftest import clean_env

    p = subprocess.Popen([str(pupper_bin), "recommend", "--trials", "64", "--batch", "4", "--robots", "8", "-q",
                          "-o", str(tmp_path / "r")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=clean_env())
    # until the first generation is in trials.csv, then mid-search
    deadline = time.time() + 600
    while not (tmp_path / "r" / "trials.csv").exists() and time.time() < deadline and p.poll() is None:
        time.sleep(0.2)
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert len(err.strip().splitlines()) == 1 and "recommend stopped" in err and "trials.csv" in err, err
    with open(tmp_path / "r" / "trials.csv", newline="") as f:
        assert len(list(csv.DictReader(f))) >= 4


def test_the_report_opens_with_the_card_in_chromium(default_run, tmp_path):
    from test_report import CHROMIUM, answer_of, browse, check_page, embedded, few_digits

    if CHROMIUM is None:
        pytest.skip("needs Debian's chromium (make test installs it)")
    d, _ = default_run
    empty = tmp_path / "empty.html"
    empty.write_text("<!DOCTYPE html><html><body></body></html>")
    dom = check_page(d, tmp_path, browse(empty, tmp_path)["urls"])
    answer = answer_of(dom)
    # every group's gains in the opening, every digit in the tooltip
    for g, c in cards(d).items():
        assert f'<td title="{g}">{g}</td><td title="{c["kp"]}">' in answer and f'<td title="{c["kd"]}">' in answer
    m = json.loads((d / "manifest.json").read_text())
    import html

    for w in m["warnings"]:
        assert html.escape(w)[:60] in answer, w
    few_digits(dom)
    embedded(dom)
    # the trade-off figure stars the pick
    assert dom.count(">★<title>") == 1


def test_the_margin_window_ends_where_the_margins_do():
    # the knee's stiffest kp that holds, found between the map's grid rows:
    # margins held there (kd mid-window), not 1 % stiffer at any kd of the range
    from pupper_core._recommend import plan_for as make_plan
    from pupper_core._recommend.search import margins, window

    plan = make_plan(robots=8)
    g = next(g for g in plan.groups if g.name == "kfe")
    w = window(plan, g)
    top = w.kp_span()[1]
    lo, hi = w.kd_span(top)
    pm, gm = margins(plan, g, top, (lo * hi) ** 0.5)
    assert pm >= plan.min_phase_margin and gm >= plan.min_gain_margin
    for kd in np.geomspace(*g.kd_range, 200):
        pm, gm = margins(plan, g, top * 1.01, float(kd))
        assert pm < plan.min_phase_margin or gm < plan.min_gain_margin, kd


def test_no_gains_run_twice_and_none_twice_in_the_tradeoff_set(default_run):
    d, _ = default_run
    with open(d / "trials.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    gains = lambda r: tuple(r[k] for k in r if k.startswith(("kp.", "kd.")))  # noqa: E731
    ran = [gains(r) for r in rows if int(r["cell_steps"]) > 0]
    assert len(ran) == len(set(ran))
    with open(d / "tradeoffs.csv", newline="") as f:
        front = [gains(r) for r in csv.DictReader(f)]
    assert len(front) == len(set(front))


def test_a_run_over_an_older_one_leaves_none_of_its_answer(run, tmp_path, default_run):
    # --force over a run that found gains, with a sensing delay no gains survive:
    # no card, exports or trade-off set of the old run stay beside the new one
    import shutil

    d = tmp_path / "rec"
    shutil.copytree(default_run[0], d)
    p = run("recommend", "--robots", "8", "--trials", "2", "--batch", "2", "--polish", "0", "--sensing-delay", "0.006",
            "--force", "-q", "-o", d, check=3)
    assert "no gains held every constraint" in p.stdout
    # an answer or a clear no (issue 59): the best available, short of what was asked, and the gains in use
    assert "best available (the candidate that came closest to holding)" in p.stdout and "in use (" in p.stdout
    for gone in ("recommend.csv", "tradeoffs.csv", "recommended.yaml", "recommended.xml"):
        assert not (d / gone).exists(), gone
    assert json.loads((d / "manifest.json").read_text())["pick"] is None
    assert "No gains held every constraint" in (d / "report.html").read_text()
