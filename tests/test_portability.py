"""No tracked file may name a directory of the machine it was written on.

A clone elsewhere has none of them: an absolute path into a home directory, a
temporary directory or this checkout works only where it was written (once,
python/requirements.lock held an editable install of the checkout by its
absolute path, and both README commands failed on every other machine).

The guard scans every tracked text file (`git ls-files`), this one included,
so the patterns below are composed from pieces and no literal forbidden path
appears in this file. `test_guard_can_fail` proves it reports what it should.
"""

from __future__ import annotations

import os
import re
import subprocess
from collections.abc import Iterable
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
MAX_TEXT = 120
BINARY_SNIFF = 8192

S = "/"
#: Before a path: not part of a longer word or a relative path (`../x`, `a/x`, `~/x`).
START = r"(?<![\w.~$-])"
#: After a directory name: the end of that path component.
END = r"(?![\w.@+-])"
#: One path component (a user name, a temp directory's name).
NAME = r"[\w.@+-]+"


def _machine_patterns(roots: Iterable[str | Path]) -> list[tuple[str, re.Pattern[str]]]:
    pats = [
        ("home directory", S + "home" + S + NAME + END),
        ("home directory", S + "Users" + S + NAME + END),
        ("home directory", S + "root" + END),
        ("home directory", r"\b[A-Za-z]:\\\\?" + "Users" + r"\\"),
        ("temporary directory", S + "tmp" + S + NAME),
        ("temporary directory", S + "var" + S + "tmp" + S),
        ("temporary directory", S + "private" + S + "var" + S + "folders" + S),
    ]
    seen: set[str] = set()
    for root in roots:
        root = str(root).rstrip("/")
        for path, what, end in (
            (root, "this checkout", END),
            # the checkout's parent only as a directory prefix (then "/"), never a longer name
            (root.rsplit("/", 1)[0], "the checkout's parent directory", S),
        ):
            # never "/" itself, nor a path too short to mean a machine (a checkout at /x)
            if path.count("/") < 1 or len(path) < 3 or path in seen:
                continue
            seen.add(path)
            pats.append((f"{what} ({path})", re.escape(path) + end))
    return [(what, re.compile(START + p)) for what, p in pats]


def _excerpt(line: str, start: int) -> str:
    text = line.strip()
    start -= len(line) - len(line.lstrip())
    if len(text) <= MAX_TEXT:
        return text
    lo = max(0, min(start - 40, len(text) - MAX_TEXT))
    cut = text[lo:lo + MAX_TEXT]
    return ("…" if lo else "") + cut + ("…" if lo + MAX_TEXT < len(text) else "")


def find_machine_paths(files: dict[str, str], roots: Iterable[str | Path]) -> list[str]:
    """`file:line: text` for every line of `files` (name -> text) naming a machine's directory.

    Flagged: home directories, temporary directories, and each checkout root in
    `roots` or anything under its parent directory. One entry per offending
    line, in file then line order; text trimmed to about 120 characters
    around the first offending path.
    """
    patterns = _machine_patterns(roots)
    found = []
    for name in sorted(files):
        for lineno, line in enumerate(files[name].splitlines(), 1):
            hits = [m.start() for _, p in patterns for m in [p.search(line)] if m]
            if hits:
                found.append(f"{name}:{lineno}: {_excerpt(line, min(hits))}")
    return found


def tracked_text_files(repo: Path) -> dict[str, str]:
    """The tracked files of `repo` that are text (no NUL in the first 8 KB, valid UTF-8)."""
    try:
        out = subprocess.run(
            ["git", "-C", str(repo), "ls-files", "-z"],
            capture_output=True, check=True, timeout=60,
        ).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        pytest.skip(f"not a git checkout, or no git ({e}): nothing tracked to scan")
    files = {}
    for raw in out.split(b"\0"):
        if not raw:
            continue
        name = raw.decode("utf-8", "surrogateescape")
        path = repo / name
        if not path.is_file() or path.is_symlink():
            continue  # deleted in the working tree, a submodule, or a link
        data = path.read_bytes()
        if b"\0" in data[:BINARY_SNIFF]:
            continue
        try:
            files[name] = data.decode("utf-8")
        except UnicodeDecodeError:
            continue
    return files


def _roots() -> list[Path]:
    return [REPO, Path(__file__).absolute().parent.parent]


def test_no_tracked_file_names_a_machine_path():
    files = tracked_text_files(REPO)
    assert files, f"git ls-files found no text files in {REPO}"
    found = find_machine_paths(files, _roots())
    assert not found, (
        f"{len(found)} line(s) of tracked files name a directory of this machine "
        "(a home or temporary directory, or this checkout by its absolute path), "
        "which a clone elsewhere does not have; use a path relative to the checkout "
        "(found at run time) instead:\n  " + "\n  ".join(found)
    )


def test_guard_can_fail():
    home = S + "home" + S + "alice" + S + ".cache"
    tmp = S + "tmp" + S + "pytest-of-root" + S + "x"
    parent = str(REPO.parent).rstrip("/")
    files = {
        "python/requirements.lock": f"numpy==2.0\n-e {REPO}/python\nscipy==1.0\n",
        "notes.md": f"# notes\n\ncache in {home}\nscratch: {tmp}\n",
        "a.toml": f'x = "ok"\n\ny = "{parent}/shared/reference"\n',
        "b.sh": "cd " + S + "root" + S + "src && make\n" + "HOME=" + S + "Users" + S + "bob make\n",
        "c.txt": "build in " + S + "var" + S + "tmp" + S + "b and "
        + S + "private" + S + "var" + S + "folders" + S + "xy/T/z\n",
        "long.txt": "x" * 300 + f" {home} " + "y" * 300 + "\n",
    }
    found = find_machine_paths(files, [REPO])
    lines = [f.split(": ", 1)[0] for f in found]
    assert lines == [
        "a.toml:3", "b.sh:1", "b.sh:2", "c.txt:1", "long.txt:1",
        "notes.md:3", "notes.md:4", "python/requirements.lock:2",
    ], found
    assert f"python/requirements.lock:2: -e {REPO}/python" in found
    assert f"notes.md:3: cache in {home}" in found
    assert f"notes.md:4: scratch: {tmp}" in found
    long = next(f for f in found if f.startswith("long.txt:1: "))
    assert home in long and len(long) < len("long.txt:1: ") + MAX_TEXT + 5, long


def test_guard_passes_harmless_text():
    parent_name = REPO.parent.name
    harmless = "\n".join([
        "see ../shared/reference",
        "https://github.com/x/y",
        "/usr/lib/x86_64-linux-gnu",
        "/dev/null", "/proc/self", '"/"',
        "~/.cache/pip and ~/.cargo/registry", "$HOME/.cache",
        "target/release/pupper", "./tmp/x", "../tmp/y", "runs/tmp/z", "tmp/x",
        "a /tmp dir, the TMPDIR", "chroot/", "repo root/x", "/rootfs", "/root.d",
        "the homework is at /homework", "https://example.com/home/alice/x",
        f"/{parent_name}shop/x", f"/{parent_name}", f"the {parent_name}/x folder",
        f"{parent_name}s/{REPO.name}", "/users/guide", "C:/Program Files",
        "PATH=/usr/local/bin:/usr/bin:/bin",
        "file:///usr/share/doc",
    ])
    found = find_machine_paths({"h.txt": harmless}, [REPO])
    assert found == [], found


# -- the environment of a fresh machine (issue 58) -----------------------------

FRESH_ENV = REPO / "scripts" / "fresh-env"
#: What a command run by `make test` finds in its environment besides what
#: scripts/fresh-env passes: make's own, the Makefile's exports, pytest's and
#: its workers', and what a shell sets for itself.
SET_BY_THE_RUN = {
    "HOME", "PATH", "PUPPER_FRESH_ENV", "PWD", "OLDPWD", "SHLVL", "_",
    "MAKEFLAGS", "MAKELEVEL", "MFLAGS", "MAKEOVERRIDES",
    "PUPPER_PROFILE", "PUPPER_EXTRAS", "PYO3_PYTHON", "MUJOCO_GL", "PUPPER_BIN",
    "PYTEST_CURRENT_TEST", "PYTEST_XDIST_WORKER", "PYTEST_XDIST_WORKER_COUNT",
    "PYTEST_XDIST_TESTRUNUID", "PYTEST_VERSION", "COLUMNS", "LINES",
    # set inside the test process itself: CPython's coercion of the C locale
    # (PEP 538), PyOpenGL's platform from MUJOCO_GL, Ray's on import
    "LC_CTYPE", "PYOPENGL_PLATFORM", "RAY_CLIENT_MODE",
}


def test_fresh_env_passes_home_and_a_plain_path_and_nothing_else(tmp_path):
    """`.ci/run` runs `make test` through scripts/fresh-env: whatever the
    calling shell holds (PYTHONUNBUFFERED on a developer's machine, an
    activated venv), the command sees HOME, a plain PATH and its marker."""
    ci = (REPO / ".ci" / "run").read_text()
    assert "exec scripts/fresh-env .ci/run" in ci and "\nmake test\n" in ci, ci
    inherited = {**os.environ, "PYTHONUNBUFFERED": "1", "VIRTUAL_ENV": str(tmp_path),
                 "PUPPER_SOMETHING": "x", "CARGO_TARGET_DIR": str(tmp_path)}
    out = subprocess.run([str(FRESH_ENV), "env"], capture_output=True, text=True, env=inherited,
                         check=True, timeout=60).stdout
    got = dict(line.split("=", 1) for line in out.splitlines())
    home = os.environ["HOME"]
    assert got == {"HOME": home, "PATH": f"/usr/local/bin:/usr/bin:/bin:{home}/.cargo/bin",
                   "PUPPER_FRESH_ENV": "1"}, got


def test_under_ci_no_test_inherits_a_variable():
    """In the run `.ci/run` starts, the tests' own environment holds only
    what fresh-env, make, the Makefile and pytest put there: a test that
    passes only with some variable of the developer's machine fails there,
    as it would on a fresh machine."""
    if os.environ.get("PUPPER_FRESH_ENV") != "1":
        pytest.skip("not under scripts/fresh-env (.ci/run): the developer's environment is inherited")
    extra = sorted(set(os.environ) - SET_BY_THE_RUN)
    assert not extra, f"variables the fresh environment does not set reached the tests: {extra}"


@pytest.mark.parametrize("unbuffered", [None, "1"])
def test_output_keeps_its_order_whatever_pythons_buffering(pupper_bin, tmp_path, unbuffered):
    """A Python-run command (a fit that warns) prints its table, then its
    warnings, then its closing lines, in that order on a merged stream,
    with PYTHONUNBUFFERED unset (a fresh machine) as with it set: off a
    terminal CPython buffered stdout in blocks, and the warnings on stderr
    overtook the table (issue 58)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    if unbuffered:
        env["PYTHONUNBUFFERED"] = unbuffered
    p = subprocess.run([str(pupper_bin), "fit",
                        str(REPO / "docs" / "sample_joint_log.csv"), "--params", "damping,lag",
                        "--max-iters", "2", "-o", str(tmp_path / "fit")],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                       cwd=tmp_path, timeout=300)
    assert p.returncode == 0, p.stdout
    lines = p.stdout.splitlines()
    kinds = ["table" if ln.startswith(("parameter ", "damping ", "lag ")) else
             "warning" if ln.startswith("warning: ") else
             "closing" if ln.startswith(("fitted in ", "wrote ")) else "other" for ln in lines]
    assert "warning" in kinds, p.stdout  # the case the order matters in
    order = [k for k in kinds if k != "other"]
    assert order == sorted(order, key=["table", "warning", "closing"].index), p.stdout


@pytest.fixture(scope="module")
def shared_once() -> str:
    """A fixture of this module's own, as a sweep or a wheel is elsewhere."""
    return "once"


def test_tests_sharing_a_fixture_run_on_one_worker(request, shared_once):
    """Under `make test` (pytest-xdist, --dist loadgroup) a test that shares
    a module fixture carries its module's group: with pytest 9.2 and xdist
    3.8 it did not, and two workers built one wheel at once."""
    if not request.config.getvalue("loadgroup"):
        pytest.skip("not under pytest-xdist's --dist loadgroup (PUPPER_TEST_WORKERS=0, or no xdist)")
    assert request.node.nodeid.endswith("@test_portability"), request.node.nodeid
