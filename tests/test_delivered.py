"""Margins on the gains the motor delivers (issue 47, item 1).

A calibrated model says, through its gain scales (`pupper:kp_scale:ACT`,
`pupper:kd_scale:ACT`, as `pupper fit` writes them), that its motors
deliver other gains than they are commanded. Every loop margin pupper
states must be of the delivered gains: `pupper gains`, and the card of
`recommend --from-fit`. Here stand-in logs of a motor that delivers 2.5x
its kp and 2x its kd are fitted, and the card's margins are checked
against `pupper gains` on the calibrated model and against this file's own
loop model on the delivered gains.
"""

from __future__ import annotations

import csv
import math
import json
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "examples"))

#: the stand-in's motor: 2.5x the kp and 2x the kd it is told
SCALE_KP, SCALE_KD = 2.5, 2.0
MOTOR = "rate=500,counts=16384"
SENSING = 0.002


def loop_phase_margin(inertia: float, kp: float, kd: float, latency: float, d_delay: float) -> float:
    """180° + arg L at |L| = 1 for L = (kp + kd s e^{-s d}) e^{-s tau} / (J s^2):
    an independent scan in frequency."""
    w = np.logspace(-1, 5, 400001)
    ctrl = kp + kd * 1j * w * np.exp(-1j * w * d_delay)
    k = int(np.argmax(np.abs(ctrl) / (inertia * w**2) <= 1.0))
    return float(np.degrees(np.angle(ctrl[k]) - w[k] * latency))


def sampled_phase_margin(inertia: float, damping: float, kp: float, kd: float, h: float, late: float,
                         lag: float = 0.0) -> float:
    """The same PD acting every physics step of ``h`` s, as the simulation
    steps it (a calibrated model's loop): 180° + arg L at |L| = 1 for the
    loop written out in z = e^{jwh} and scanned up to Nyquist. Semi-implicit
    Euler, v' = (v + h·u/J)/(1 + h·b/J), q' = q + h·v', puts h²·z /
    (J·(z − 1)·((1 + hb/J)·z − 1)) from torque to angle; the PD reads the
    state ``late`` steps old (between two steps: linearly), its velocity
    the angle's difference over a step; a torque ``lag`` follows
    y' = y + a·(u − y), a = 1 − e^{−h/lag}."""
    w = np.linspace(1e-3, np.pi / h, 400001)[:-1]
    z = np.exp(1j * w * h)
    joint = h * h * z / (inertia * (z - 1) * ((1 + h * damping / inertia) * z - 1))
    whole, frac = divmod(late, 1.0)
    old = z ** -whole * ((1 - frac) + frac / z)
    a = -np.expm1(-h / lag) if lag > 0 else 1.0
    follow = a / (1 - (1 - a) / z)
    loop = (kp + kd * (1 - 1 / z) / h) * joint * old * follow
    k = int(np.argmax(np.abs(loop) <= 1.0))
    return float(180.0 + np.degrees(np.unwrap(np.angle(loop))[k]))


def sampled_gain_margin(inertia: float, damping: float, kp: float, kd: float, h: float, late: float) -> float:
    """The same loop's gain margin (dB): −20·log10 |L| where its phase
    crosses −180° above the gain crossover, at the latest at Nyquist (where
    a sampled loop's phase comes back to the real axis); inf where it
    never does."""
    w = np.linspace(1e-3, np.pi / h * (1 - 1e-9), 400001)
    z = np.exp(1j * w * h)
    whole, frac = divmod(late, 1.0)
    loop = ((kp + kd * (1 - 1 / z) / h) * h * h * z * z ** -whole * ((1 - frac) + frac / z)
            / (inertia * (z - 1) * ((1 + h * damping / inertia) * z - 1)))
    phase = np.degrees(np.unwrap(np.angle(loop)))
    above = np.abs(loop) <= 1.0
    cross = np.flatnonzero(above & (phase <= -180.0 + 1e-6))
    return float(-20 * np.log10(np.abs(loop[cross[0]]))) if cross.size else math.inf


def joint_damping(model: Path) -> dict[str, float]:
    """Each actuator's joint's viscous damping (N·m·s/rad), read by MuJoCo."""
    m = mujoco.MjModel.from_xml_path(str(model))
    return {m.actuator(a).name: float(m.dof_damping[m.jnt_dofadr[m.actuator_trnid[a, 0]]]) for a in range(m.nu)}


def scaled_model(tmp: Path, kp: float, kd: float) -> Path:
    """The built-in robot whose every motor delivers SCALE_KP x kp and
    SCALE_KD x kd, written as `pupper fit` writes a calibrated model."""
    import pupper_core as pc

    spec = mujoco.MjSpec.from_file(str(Path(pc.__file__).parent / "models" / "pupper_v3" / "pupper_v3.xml"))
    for a in spec.actuators:
        spec.add_numeric(name=f"pupper:kp_scale:{a.name}", data=[kp])
        spec.add_numeric(name=f"pupper:kd_scale:{a.name}", data=[kd])
    path = tmp / "scaled.xml"
    path.write_text(spec.to_xml())
    return path


def test_gains_states_the_margins_of_the_delivered_gains(run, tmp_path):
    model = scaled_model(tmp_path, SCALE_KP, SCALE_KD)
    args = ("--kp", "16.71", "--kd", "0.2646", "--motor", MOTOR, "--sensing-delay", str(SENSING), "--json")
    scaled = json.loads(run("gains", "--model", model, *args, check=0).stdout)
    plain = json.loads(run("gains", *args, check=0).stdout)
    damping = joint_damping(model)
    for js, jp in zip(scaled["joints"], plain["joints"]):
        assert js["actuator"] == jp["actuator"] and js["inertia"] == pytest.approx(jp["inertia"])
        # commanded as given, delivered scaled
        assert (js["kp"], js["kd"]) == (16.71, 0.2646)
        assert js["delivered"] == pytest.approx([16.71 * SCALE_KP, 0.2646 * SCALE_KD])
        assert "delivered" not in jp
        # the calibrated model: the loop its fit was made through, the
        # 500 Hz PD acting every 2 ms step on the state one step old
        want = sampled_phase_margin(js["inertia"], damping[js["actuator"]], 16.71 * SCALE_KP,
                                    0.2646 * SCALE_KD, 0.002, SENSING / 0.002)
        assert js["phase_margin_deg"] == pytest.approx(want, abs=0.3)
        # the nominal one: the continuous loop, latency 2 ms sensing + half
        # the 2 ms period, the derivative 1 ms more
        assert jp["phase_margin_deg"] == pytest.approx(loop_phase_margin(jp["inertia"], 16.71, 0.2646, 0.003,
                                                                         0.001), abs=0.3)
        # the commanded gains in the very same loop: more margin
        assert sampled_phase_margin(js["inertia"], damping[js["actuator"]], 16.71, 0.2646, 0.002,
                                    SENSING / 0.002) > js["phase_margin_deg"] + 5
    # the knee: comfortable on the commanded gains, close to the edge on the delivered ones
    knee_s = next(j for j in scaled["joints"] if j["actuator"] == "leg_front_r_3")
    knee_p = next(j for j in plain["joints"] if j["actuator"] == "leg_front_r_3")
    assert knee_p["phase_margin_deg"] > 30 > knee_s["phase_margin_deg"]
    # the natural frequency is the delivered kp's
    assert knee_s["natural_hz"] == pytest.approx(knee_p["natural_hz"] * SCALE_KP ** 0.5)
    text = run("gains", "--model", model, *args[:-1], check=0).stdout
    assert "motor kp" in text and "what the motor delivers" in text
    assert "motor kp" not in run("gains", *args[:-1], check=0).stdout


def test_a_bandwidth_asks_for_the_commanded_gains_that_deliver_it(run, tmp_path):
    model = scaled_model(tmp_path, SCALE_KP, SCALE_KD)
    scaled = json.loads(run("gains", "--model", model, "--bandwidth", "8", "--json", check=0).stdout)
    plain = json.loads(run("gains", "--bandwidth", "8", "--json", check=0).stdout)
    for gs, gp in zip(scaled["groups"], plain["groups"]):
        assert gs["kp"] == pytest.approx(gp["kp"] / SCALE_KP)
        assert gs["kd"] == pytest.approx(gp["kd"] / SCALE_KD)
        assert gs["natural_hz"] == pytest.approx(gp["natural_hz"])


@pytest.fixture(scope="module")
def scaled_fit(pupper_bin, tmp_path_factory):
    """A fit of two noise-free stand-in logs of a knee whose motor delivers
    2.5x its kp and 2x its kd, then recommend --from-fit on it."""
    pytest.importorskip("optuna")
    pytest.importorskip("scipy")
    import subprocess

    from conftest import clean_env
    from stand_log import COLUMNS, PLAIN, stand_log

    d = tmp_path_factory.mktemp("delivered")
    # the scales are this test's subject: the plain stand (a servo the default parameters follow)
    truth = {**PLAIN["truth"], "kp_scale": SCALE_KP, "kd_scale": SCALE_KD}
    logs = [stand_log(d / f"kd{kd}.csv", kp=2.0, kd=kd, seed=seed, noise=0.0, **{**PLAIN, "truth": truth})
            for kd, seed in ((0.05, 0), (0.15, 1))]

    def pupper(*args: object) -> subprocess.CompletedProcess[str]:
        p = subprocess.run([str(pupper_bin), *map(str, args)], capture_output=True, text=True, cwd=d,
                           env=clean_env(), timeout=900)
        assert p.returncode == 0, p.stderr[-3000:]
        return p

    pupper("fit", *logs, "--columns", COLUMNS, "-o", d / "fit")
    # no leg-mass spread: the group's inertia is the model's, so the card's
    # worst corner is a joint `pupper gains` states
    rec = pupper("recommend", "--from-fit", d / "fit", "--spread", "torso_mass=±15%", "--robots", "8",
                 "--trials", "8", "--batch", "8", "--polish", "0", "-o", d / "rec")
    return d, rec


def test_recommend_from_a_fit_checks_its_margins_on_the_delivered_gains(scaled_fit, run):
    d, rec = scaled_fit
    with open(d / "fit" / "fit.csv", newline="") as f:
        fitted = {r["parameter"]: float(r["fitted"]) for r in csv.DictReader(f)}
    assert fitted["kp_scale"] == pytest.approx(SCALE_KP, rel=0.02)
    assert fitted["kd_scale"] == pytest.approx(SCALE_KD, rel=0.05)
    with open(d / "rec" / "recommend.csv", newline="") as f:
        cards = {r["group"]: r for r in csv.DictReader(f)}
    knee = cards["kfe"]
    kp, kd = float(knee["kp"]), float(knee["kd"])
    # the card says what the motor delivers of its gains
    assert float(knee["motor_kp"]) == pytest.approx(kp * fitted["kp_scale"], rel=1e-3)
    assert float(knee["motor_kd"]) == pytest.approx(kd * fitted["kd_scale"], rel=1e-3)
    assert "motor kp" in rec.stdout and "the gains to command" in rec.stdout
    yaml_text = (d / "rec" / "recommended.yaml").read_text()
    assert "the gains to command" in yaml_text and "the motors deliver" in yaml_text
    # the card's margins are what `pupper gains` states at the card's gains
    # on every robot the fit's logs allow (its robots.csv, each written into
    # the calibrated model here) and on the fitted one: their worst joint
    models = [d / "fit" / "calibrated.xml", *robot_models(d / "fit", d / "drawn")]
    assert len(models) == 1 + 8
    m = json.loads((d / "rec" / "manifest.json").read_text())
    # the robots carry the motor's gains: no spread of its own on top
    assert m["inputs"]["kp_factors"] == [1.0, 1.0] == m["inputs"]["kd_factors"]
    for group, card in cards.items():
        kp, kd = float(card["kp"]), float(card["kd"])
        stated = []
        for model in models:
            g = json.loads(run("gains", "--model", model, "--kp", kp, "--kd", kd, "--json", check=0).stdout)
            damping = joint_damping(model)
            for j in (j for j in g["joints"] if j["group"] == group):
                sp, sd = (numeric(model, f"pupper:{k}_scale:{j['actuator']}") for k in ("kp", "kd"))
                assert j["delivered"] == pytest.approx([kp * sp, kd * sd], rel=1e-5)
                stated.append((j["phase_margin_deg"], j["gain_margin_db"], j["inertia"],
                               damping[j["actuator"]], sp, sd))
        worst_pm = min(stated)
        assert float(card["phase_margin_deg"]) == pytest.approx(worst_pm[0], abs=0.05), (group, worst_pm)
        assert float(card["gain_margin_db"]) == pytest.approx(min(s[1] for s in stated), abs=0.02), group
        # the stated margin holds there, and this file's own loop model agrees
        # (the fit's firmware is the ideal servo: the PD every step on the state now)
        assert worst_pm[0] >= 30 - 0.05
        _, _, inertia, damping_, sp, sd = worst_pm
        own = sampled_phase_margin(inertia, damping_, kp * sp, kd * sd, 0.002, 0.0)
        assert own == pytest.approx(worst_pm[0], abs=0.3) and own >= 30 - 0.3
        worst_gm = min(stated, key=lambda s: s[1])
        own_gm = sampled_gain_margin(worst_gm[2], worst_gm[3], kp * worst_gm[4], kd * worst_gm[5], 0.002, 0.0)
        assert own_gm == pytest.approx(float(card["gain_margin_db"]), abs=0.1)
        # a card closed on the commanded gains would state another margin: the test can tell
        assert sampled_gain_margin(worst_gm[2], worst_gm[3], kp, kd, 0.002, 0.0) > own_gm + 3


def numeric(model: Path, name: str) -> float:
    """A custom numeric's value (1 where the model has none)."""
    m = mujoco.MjModel.from_xml_path(str(model))
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, name)
    return 1.0 if i < 0 else float(m.numeric_data[m.numeric_adr[i]])


def robot_models(fit: Path, out: Path) -> list[Path]:
    """Each robot of a fit's robots.csv as a model: its calibrated.xml with
    the robot's values of the fit's rows written over it (joint armature and
    damping, the motors' gain scales), written here by MjSpec."""
    with open(fit / "fit.csv", newline="") as f:
        goes_to = {r["parameter"]: r["actuators"].split() for r in csv.DictReader(f)}
    with open(fit / "robots.csv", newline="") as f:
        robots = list(csv.DictReader(f))
    out.mkdir(exist_ok=True)
    paths = []
    for r in robots:
        spec = mujoco.MjSpec.from_file(str(fit / "calibrated.xml"))
        joint_of = {a.name: a.target for a in spec.actuators}
        numerics = {n.name: n for n in spec.numerics}
        for parameter, actuators in goes_to.items():
            kind, v = parameter.partition(".")[0], float(r[parameter])
            for a in actuators:
                if kind == "armature":
                    spec.joint(joint_of[a]).armature = v
                elif kind == "damping":  # the viscous term of MuJoCo's damping polynomial
                    joint = spec.joint(joint_of[a])
                    joint.damping = [v, *joint.damping[1:]]
                elif kind in ("kp_scale", "kd_scale"):
                    numerics[f"pupper:{kind}:{a}"].data = [v]
        path = out / f"robot{r['robot']}.xml"
        path.write_text(spec.to_xml())
        paths.append(path)
    return paths


#: a robot's controller configuration as Pupper v3's ROS 2 launch files hold
#: it: the node's joint names and the gains it commands
ROBOT_CONFIG = """\
controller_manager:
  ros__parameters:
    update_rate: 500
neural_controller:
  ros__parameters:
    joint_names: [leg_front_r_1, leg_front_r_2, leg_front_r_3, leg_front_l_1, leg_front_l_2, leg_front_l_3,
                  leg_back_r_1, leg_back_r_2, leg_back_r_3, leg_back_l_1, leg_back_l_2, leg_back_l_3]
    init_kps: [7.5, 7.5, 7.5, 7.5, 7.5, 7.5, 7.5, 7.5, 7.5, 7.5, 7.5, 7.5]
    init_kds: [0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25]
"""


def test_the_card_sets_the_gains_in_use_beside_the_pick(run, tmp_path):
    pytest.importorskip("optuna")
    cfg = tmp_path / "config.yaml"
    # the robot's own joint order: the left legs first
    cfg.write_text(ROBOT_CONFIG.replace("leg_front_r_1, leg_front_r_2, leg_front_r_3, leg_front_l_1, leg_front_l_2, "
                                        "leg_front_l_3", "leg_front_l_1, leg_front_l_2, leg_front_l_3, leg_front_r_1, "
                                        "leg_front_r_2, leg_front_r_3"))
    p = run("recommend", "--robot-config", cfg, "--robots", "8", "--trials", "4", "--batch", "4", "--polish", "0",
            "--kp-max", "40", "--kd-max", "1", "-o", tmp_path / "rec", check=0)
    line = next(x for x in p.stdout.splitlines() if x.startswith("in use"))
    assert "config.yaml's kps and kds: kp 7.5 kd 0.25 on every group" in line
    m = json.loads((tmp_path / "rec" / "manifest.json").read_text())
    now = m["current"]
    assert now["gains"] == {g: {"kp": 7.5, "kd": 0.25} for g in ("hfe", "haa", "kfe")}
    # the gains in use were checked as every candidate is: the same loop model
    knee = json.loads(run("gains", "--kp", "7.5", "--kd", "0.25", "--motor", MOTOR, "--sensing-delay", "0",
                          "--json", check=0).stdout)
    assert now["phase_margin_deg"]["kfe"] <= min(j["phase_margin_deg"] for j in knee["joints"]
                                                  if j["group"] == "kfe")
    assert np.isfinite(now["p95_push_dip_mm"]) and now["fell"] == 0
    # the YAML follows the robot's joint order; caps were given: no caps warning
    yml = (tmp_path / "rec" / "recommended.yaml").read_text()
    assert "joint_names: [leg_front_l_1, leg_front_l_2, leg_front_l_3, leg_front_r_1" in yml
    assert "no motor caps given" not in p.stdout
    # a config that is not one is refused in one line, nothing written
    cfg.write_text("neural_controller: [1, 2]\n")
    bad = run("recommend", "--robot-config", cfg, "-o", tmp_path / "bad", check=2)
    assert "no 'neural_controller: ros__parameters:' section" in bad.stderr and len(bad.stderr.splitlines()) == 1
    assert not (tmp_path / "bad").exists()


def test_recommend_from_a_fit_assumes_its_fitted_latency_and_says_so(tmp_path):
    """Issues 48 and 59: recommend --from-fit closes its loops on the
    feedback latency the fit measured, each robot the logs allow on its own
    draw of it (never a default stacked on top), and says which latency it
    assumed and where it came from; --sensing-delay still wins."""
    pytest.importorskip("scipy")
    import pupper_core as pc
    from pupper_core._recommend import plan_for as plan
    from stand_log import COLUMNS, PLAIN, stand_log

    # two kps: the latency (inside the loop) is told from the delay (outside it)
    logs = [stand_log(tmp_path / f"kp{kp}.csv", kp=kp, kd=0.1, seed=0, noise=0.0,
                      **{**PLAIN, "truth": {**PLAIN["truth"], "latency": 0.004}}) for kp in (5.0, 10.0)]
    pc.fit(logs, columns=COLUMNS, params="kp_scale,delay,latency", max_iters=4, progress=False,
           out=tmp_path / "fit")
    with open(tmp_path / "fit" / "fit.csv", newline="") as f:
        lat = next(r for r in csv.DictReader(f) if r["parameter"] == "latency")
    with open(tmp_path / "fit" / "robots.csv", newline="") as f:
        drawn = sorted(float(r["latency"]) for r in csv.DictReader(f))
    p = plan(from_fit=tmp_path / "fit", robots=8)
    # no sensing delay of recommend's own: the loops carry the fit's latency
    assert p.sensing_delay is None and p.latency_words() == "the fit's own latency"
    latencies = sorted({lp.latency for g in p.groups for lp in g.loops})
    fitted = float(lat["fitted"])
    assert latencies == pytest.approx(sorted({round(v, 12) for v in [fitted, *drawn]}), rel=1e-6)
    assert float(lat["low95"]) - 1e-9 <= min(drawn) and max(drawn) <= float(lat["high95"]) + 1e-9
    assert p.latency_from.startswith("the loop the fit found: ")
    assert "feedback latency the fit's, each robot its own (fit.csv: latency" in p.latency_from, p.latency_from
    assert "command delay the fit's, each robot its own (fit.csv: delay" in p.latency_from, p.latency_from
    assert p.inputs()["latency_from"] == p.latency_from
    given = plan(from_fit=tmp_path / "fit", robots=8, sensing_delay=0.001)
    assert given.sensing_delay == 0.001
    assert "feedback latency 0.001 s, given by --sensing-delay (the fit measured" in given.latency_from
    # no fit: the default, and nothing said (earlier cards unchanged)
    assert plan(robots=8).sensing_delay == 0.002 and plan(robots=8).latency_from == ""
