"""The README's set-up works from a fresh clone, with this checkout out of sight.

Runs scripts/check-fresh-clone.sh on HEAD: it clones the committed HEAD into a
temporary directory, hides this checkout (an empty tmpfs over it, in a private
mount namespace), and there runs `PUPPER_PROFILE=debug make sweep` and a 2-cell
sweep with the binary it built. It takes minutes (a venv and two debug builds);
set PUPPER_SKIP_FRESH_CLONE=1 to leave it out. It needs root on Linux with
unshare(1): elsewhere the script exits 77 and the test is skipped with its reason.
"""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SCRIPT = REPO / "scripts" / "check-fresh-clone.sh"
TIMEOUT_S = 20 * 60
SKIPPED = 77
TAIL_LINES = 80


def _stop(proc: subprocess.Popen) -> str:
    """Stops the script and everything it started (its own process group); its output."""
    for sig, grace in ((signal.SIGTERM, 60), (signal.SIGKILL, 30)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            pass
        try:
            return proc.communicate(timeout=grace)[0] or ""
        except subprocess.TimeoutExpired:
            continue
    return ""


def test_readme_setup_works_from_a_fresh_clone():
    if os.environ.get("PUPPER_SKIP_FRESH_CLONE", "") not in ("", "0"):
        pytest.skip("PUPPER_SKIP_FRESH_CLONE is set: the fresh-clone set-up check is left out")
    dirty = subprocess.run(
        ["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=no"],
        capture_output=True, text=True,
    ).stdout.rstrip("\n")
    if dirty.strip():
        print("note: uncommitted changes to tracked files are not part of this check; "
              "it sets up HEAD as committed:\n" + dirty)

    proc = subprocess.Popen(
        ["bash", str(SCRIPT), "HEAD"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
        text=True, errors="replace", start_new_session=True,
    )
    try:
        out, _ = proc.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        out = _stop(proc)
        tail = "\n".join(out.splitlines()[-TAIL_LINES:])
        pytest.fail(f"{SCRIPT.name} ran past {TIMEOUT_S} s and was stopped; its last lines:\n{tail}",
                    pytrace=False)
    except BaseException:  # Ctrl-C: take the builds down too, and let the script clean up
        _stop(proc)
        raise
    print(out)

    if proc.returncode == SKIPPED:
        reasons = [line.split("skipped:", 1)[1].strip()
                   for line in out.splitlines() if "skipped:" in line]
        pytest.skip(f"{SCRIPT.name}: " + (reasons[-1] if reasons else "cannot run here (exit 77)"))
    tail = "\n".join(out.splitlines()[-TAIL_LINES:])
    assert proc.returncode == 0, (
        f"the README set-up fails from a fresh clone of HEAD: {SCRIPT.name} exited "
        f"{proc.returncode}; its last {TAIL_LINES} lines:\n{tail}"
    )
