#!/usr/bin/env python3
"""Screenshots of report.html for docs/: one run of each kind (sweep, lab,
response, hold, tune, fit, recommend) made with this checkout's `pupper`,
its page opened in headless Chromium (Debian's `chromium`) at 1200 x 1800,
saved as docs/report_<kind>.png.

With --before REV, the same run directories also get the page that the
report code of commit REV writes (its python/pupper_core, taken with
`git archive`, run on a copy of each directory with this checkout's
compiled module), saved as docs/report_<kind>_before.png, for the kinds
that REV knew. Issue 40's pictures started after deace3f:

    .venv/bin/python scripts/report_screenshots.py --before deace3f

Needs the tune extra (Optuna) and the fit extra for tune, fit and
recommend; a few minutes on two cores.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DOCS = REPO / "docs"

#: Each kind's run: the commands, run in the work directory; the last
#: writes the run directory named after the kind.
RUNS: dict[str, list[list[str]]] = {
    "sweep": [["sweep", "--grid", "kp=10,30,60,120", "--grid", "kd=0.5,1,2,5", "--seconds", "4", "-q",
               "-o", "sweep"]],
    "lab": [["lab", "--seconds", "4", "-q", "-o", "lab"]],
    "response": [["response", "--grid", "kp=5,20,60", "--grid", "kd=0.1,0.5", "--plot", "-q", "-o", "response"]],
    "hold": [["hold", "--grid", "kp=5,10,20,40", "--grid", "kd=0.25,0.5,1", "-q", "-o", "hold"]],
    "tune": [["tune", "--space", "kp=5:200:log", "--space", "kd=0.05:10:log", "--trials", "32", "--batch", "16",
              "--seconds", "4", "-q", "-o", "tune"]],
    # docs/fit.md's stand-in robot: Pupper with other motors, excited
    "fit": [["@robot"],
            ["excite", "--model", "robot.xml", "--kd", "0.1", "--seconds", "3", "-o", "robot1.csv"],
            ["excite", "--model", "robot.xml", "--kd", "0.3", "--seconds", "3", "--seed", "1", "-o", "robot2.csv"],
            # a log at other gains, of sines (a chirp) for the frequency response, not fitted: the verdict's
            ["excite", "--model", "robot.xml", "--kp", "7.5", "--kd", "0.2", "--signal", "chirp", "--band", "1,12",
             "--seconds", "3", "-o", "robot3.csv"],
            ["fit", "robot1.csv", "robot2.csv", "--validate", "robot3.csv", "-o", "fit"]],
    "recommend": [["recommend", "--trials", "8", "--batch", "8", "--robots", "32", "--polish", "1", "-q",
                   "-o", "recommend"]],
}


def stand_in_robot(work: Path) -> None:
    """docs/fit.md's robot: heavier rotors, more damping and friction, a
    10 ms command delay."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(REPO / "models" / "pupper_v3" / "pupper_v3.xml"))
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
            joint.armature *= 1.3
            joint.damping[0] = 0.02
            joint.frictionloss = 0.05
    for actuator in spec.actuators:
        actuator.nsample, actuator.interp, actuator.delay = 8, 1, 0.01
    (work / "robot.xml").write_text(spec.to_xml())


def chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        sys.exit("needs Debian's chromium (apt-get install chromium)")
    return found


def shoot(page: Path, png: Path) -> None:
    """The page as headless Chromium draws it, nothing fetched from elsewhere."""
    subprocess.run([chromium(), "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                    "--hide-scrollbars", "--host-resolver-rules=MAP * ~NOTFOUND", "--window-size=1200,1800",
                    f"--screenshot={png}", page.as_uri()], check=True, capture_output=True, timeout=120)
    print(f"wrote {png.relative_to(REPO)}")


def old_package(rev: str, into: Path) -> Path:
    """python/pupper_core as commit ``rev`` had it, with this checkout's
    compiled module (the report code reads files; its helpers are few)."""
    tar = subprocess.run(["git", "-C", str(REPO), "archive", rev, "python/pupper_core"], check=True,
                         capture_output=True).stdout
    with tarfile.open(fileobj=BytesIO(tar)) as t:
        t.extractall(into, filter="data")
    pkg = into / "python" / "pupper_core"
    for so in (REPO / "python" / "pupper_core").glob("_native*.so"):
        shutil.copy2(so, pkg / so.name)
    return into / "python"


def kind_of(run_dir: Path) -> str:
    return json.loads((run_dir / "manifest.json").read_text()).get("kind", "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", metavar="REV", help="also the pages the report code of REV writes")
    ap.add_argument("--kinds", default=",".join(RUNS), help="which kinds (default: all)")
    ap.add_argument("--keep", type=Path, help="make the runs here and keep them")
    a = ap.parse_args()
    pupper = os.environ.get("PUPPER_BIN", str(REPO / "target" / "release" / "pupper"))
    kinds = [k for k in a.kinds.split(",") if k]
    with tempfile.TemporaryDirectory() as tmp:
        work = a.keep or Path(tmp) / "runs"
        work.mkdir(parents=True, exist_ok=True)
        old = old_package(a.before, Path(tmp) / "old") if a.before else None
        for kind in kinds:
            if not (work / kind / "report.html").exists():
                for args in RUNS[kind]:
                    if args == ["@robot"]:
                        stand_in_robot(work)
                        continue
                    subprocess.run([pupper, *args], cwd=work, check=True, stdout=subprocess.DEVNULL)
            shoot(work / kind / "report.html", DOCS / f"report_{kind}.png")
            if old is None:
                continue
            if f'"{kind}"' not in (old / "pupper_core" / "_report.py").read_text():
                print(f"{kind}: the report code of {a.before} has no page of its own for it (newer)")
                continue
            copy = Path(tmp) / "before" / kind
            shutil.copytree(work / kind, copy, dirs_exist_ok=True)
            (copy / "report.html").unlink()
            p = subprocess.run([sys.executable, "-c", "import sys; from pupper_core._report import report; "
                                "report(sys.argv[1])", str(copy)],
                               env={**os.environ, "PYTHONPATH": str(old)}, capture_output=True, text=True)
            if p.returncode != 0 or not (copy / "report.html").exists():
                last = (p.stderr.strip().splitlines() or ["no page"])[-1]
                print(f"{kind}: the report code of {a.before} wrote no page ({last})")
                continue
            shoot(copy / "report.html", DOCS / f"report_{kind}_before.png")


if __name__ == "__main__":
    main()
