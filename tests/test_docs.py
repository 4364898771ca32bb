"""Every example in README.md and docs/ runs, and prints what the page shows.

A fenced block is read by its language:

- ``console``: ``$ command`` lines (a trailing backslash continues one),
  each followed by what it prints, stdout and stderr as one stream. Checked
  by doctest's rules: runs of whitespace compare equal and ``...`` stands
  for any text, whole lines included. A last line ``[exit N]`` says the
  command exits N; otherwise it must exit 0.
- ``sh``: commands that must run and exit 0; their output is not shown.
- ``python``: a doctest session (``>>>``, output checked), or a plain script
  that must run without an exception.
- ``text`` (or no language): not an example (a file format, a listing); it
  may hold no command or prompt.

A block that cannot run here says why in an HTML comment on the line before
its fence: ``<!-- doc-test: skip REASON -->``, or ``<!-- doc-test:
covered-by PATH... -->`` where the files named hold every command
line of the block (the test that runs it).

Each page runs in a temporary directory of its own, its blocks in order (an
example may use the run directory an earlier one wrote), with ``docs``,
``models`` and ``examples`` of this checkout linked there and the tested
``pupper`` first on PATH. Wall times and run-directory time stamps change
from run to run; both sides have them replaced before the comparison.
"""

from __future__ import annotations

import contextlib
import doctest
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from conftest import REPO, clean_env

PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
RUN_LANGS = {"console", "sh", "python"}
TEXT_LANGS = {"", "text"}
LINKED = ("docs", "models", "examples")
COMMAND_TIMEOUT_S = 600

#: (pattern, replacement) applied to both the shown and the printed output.
VOLATILE = [
    (re.compile(r"\b\d{8}-\d{6}\b"), "YYYYMMDD-HHMMSS"),  # runs/<time>-<axes>
    (re.compile(r"\b(in|took) \d+(\.\d+)? s\b"), r"\1 T s"),  # wall time
    # off a terminal a run past 10 s says how far it is (issue 61, item 15):
    # whether a line comes depends on the machine's speed, as a wall time does
    (re.compile(r"(?m)^progress: .*\n?"), ""),
]


@dataclass
class Block:
    page: Path
    line: int  # 1-based line of the opening fence
    lang: str
    body: str
    note: str  # the doc-test comment before the fence, or ""

    def where(self) -> str:
        name = self.page.relative_to(REPO) if self.page.is_relative_to(REPO) else self.page.name
        return f"{name}:{self.line}"


FENCE = re.compile(r"^(\s*)```(\S*)\s*$")
NOTE = re.compile(r"<!--\s*doc-test:\s*(.*?)\s*-->")


def blocks(page: Path, text: str | None = None) -> list[Block]:
    lines = (page.read_text() if text is None else text).splitlines()
    out: list[Block] = []
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, lang = m.group(1), m.group(2)
        j = i + 1
        while j < len(lines) and lines[j].strip() != "```":
            j += 1
        body = "\n".join(line[len(indent):] if line.startswith(indent) else line.lstrip()
                         for line in lines[i + 1:j])
        k = i - 1
        while k >= 0 and not lines[k].strip():
            k -= 1
        note = NOTE.search(lines[k]) if k >= 0 else None
        out.append(Block(page, i + 1, lang, body + "\n", note.group(1) if note else ""))
        i = j + 1
    return out


def normalize(text: str) -> str:
    for pattern, repl in VOLATILE:
        text = pattern.sub(repl, text)
    return text


def console_steps(body: str) -> list[tuple[str, str, int]]:
    """(command, shown output, expected exit status) per `$` line."""
    steps: list[tuple[str, list[str], int]] = []
    lines = body.splitlines()
    i = 0
    while i < len(lines):
        if not lines[i].startswith("$ "):
            if not steps:
                raise ValueError(f"output before the first command: {lines[i]!r}")
            steps[-1][1].append(lines[i])
            i += 1
            continue
        cmd = lines[i][2:]
        while cmd.endswith("\\") and i + 1 < len(lines):
            i += 1
            cmd = cmd + "\n" + lines[i]
        steps.append((cmd, [], 0))
        i += 1
    out = []
    for cmd, shown, _ in steps:
        status = 0
        if shown and (m := re.fullmatch(r"\[exit (\d+)\]", shown[-1].strip())):
            status = int(m.group(1))
            shown = shown[:-1]
        out.append((cmd, "\n".join(shown) + "\n" if shown else "", status))
    return out


def matches(shown: str, printed: str) -> bool:
    return doctest.OutputChecker().check_output(normalize(shown), normalize(printed), FLAGS)


def shell(cmd: str, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    # -e: a block of several commands fails at its first failing line
    return subprocess.run(["bash", "-e", "-o", "pipefail", "-c", cmd], cwd=cwd, env=env, text=True,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=COMMAND_TIMEOUT_S)


def run_python(block: Block, globs: dict, cwd: Path) -> str:
    """'' when the block ran as shown, else what went wrong."""
    with contextlib.chdir(cwd):
        if ">>>" in block.body:
            test = doctest.DocTestParser().get_doctest(block.body, globs, block.where(), str(block.page),
                                                        block.line)
            report: list[str] = []
            # verbose=False: doctest would turn chatty under `pytest -v`
            runner = doctest.DocTestRunner(checker=_NormalizingChecker(), optionflags=FLAGS, verbose=False)
            result = runner.run(test, out=report.append, clear_globs=False)
            globs.update(test.globs)  # DocTest ran on a copy: later blocks see these names
            return ("".join(report) or "a failed example") if result.failed else ""
        try:
            exec(compile(block.body, block.where(), "exec"), globs)  # noqa: S102 - the page's own example
        except Exception as exc:  # noqa: BLE001 - any failure of the example is the finding
            return f"{type(exc).__name__}: {exc}"
        return ""


class _NormalizingChecker(doctest.OutputChecker):
    def check_output(self, want: str, got: str, optionflags: int) -> bool:
        return super().check_output(normalize(want), normalize(got), optionflags)


def covered(block: Block) -> str:
    """'' when the covering files hold every command line of the block."""
    paths = block.note.split()[1:]
    texts = []
    for path in paths:
        if not (REPO / path).is_file():
            return f"covered-by names no file of the repository: {path!r}"
        texts.append((REPO / path).read_text())
    if not texts:
        return "covered-by names no file"
    commands = [line.split("#", 1)[0].strip() for line in block.body.splitlines()]
    # a command counts where a line of a covering file starts with it
    starts = {line.strip() for t in texts for line in t.splitlines()}
    missing = [c for c in commands if c and not any(line.startswith(c) for line in starts)]
    return f"{' '.join(paths)} do not hold {missing}" if missing else ""


def check_page(page: Path, workdir: Path, pupper_bin: Path) -> list[str]:
    for name in LINKED:
        (workdir / name).symlink_to(REPO / name)
    env = clean_env(PATH=f"{pupper_bin.parent}{os.pathsep}{os.environ['PATH']}")
    globs: dict = {"__name__": "__doc_example__"}
    failures: list[str] = []
    for block in blocks(page):
        if block.note.startswith("skip"):
            if len(block.note.split()) < 3:
                failures.append(f"{block.where()}: a skip must give its reason")
            continue
        if block.note.startswith("covered-by"):
            if problem := covered(block):
                failures.append(f"{block.where()}: {problem}")
            continue
        if block.note:
            failures.append(f"{block.where()}: unknown doc-test note {block.note!r}")
            continue
        if block.lang in TEXT_LANGS:
            if re.search(r"^(\$ |>>> |pupper |make |pip )", block.body, flags=re.M):
                failures.append(f"{block.where()}: a command in a {block.lang or 'plain'} block: "
                                "make it console, sh or python, or say why it cannot run")
            continue
        if block.lang not in RUN_LANGS:
            failures.append(f"{block.where()}: unknown block language {block.lang!r}")
            continue
        if block.lang == "python":
            if problem := run_python(block, globs, workdir):
                failures.append(f"{block.where()}:\n{problem}")
            continue
        steps = (console_steps(block.body) if block.lang == "console"
                 else [(block.body, None, 0)])
        for cmd, shown, status in steps:
            proc = shell(cmd, workdir, env)
            if proc.returncode != status or (shown is not None and not matches(shown, proc.stdout)):
                failures.append(f"{block.where()}: $ {cmd}\nexit {proc.returncode} (expected {status})\n"
                                f"--- shown\n{shown}--- printed\n{proc.stdout}")
    return failures


#: A row of troubleshooting.md's table: `pupper ...` | `` error: ... ``.
ERROR_ROW = re.compile(r"^\| `(pupper [^`]*)` \| `` (error: .*?) ``(?: \(.*\))? \|$")


def error_rows(text: str) -> list[tuple[str, str]]:
    """(command, message) of each table row that is a plain command line; rows
    that need a set-up said in words (a file made unreadable, another Python)
    are tests/test_bad_input.py's."""
    return [(m.group(1), m.group(2)) for line in text.splitlines()
            if (m := ERROR_ROW.match(line)) and "  (" not in m.group(1)]


def test_every_error_in_troubleshooting_is_what_pupper_says(tmp_path: Path, pupper_bin: Path):
    text = (REPO / "docs" / "troubleshooting.md").read_text()
    rows = error_rows(text)
    # every row is read: run here, or a set-up in words (test_bad_input.py's)
    table = [line for line in text.splitlines() if line.startswith("| `pupper ")]
    cells = [line[2:].split(" | ", 1)[0] for line in table]
    in_words = [c for c in cells if "  (" in c or not re.fullmatch(r"`[^`]*`", c)]
    assert len(rows) + len(in_words) == len(table) and len(rows) >= 25, (len(rows), len(in_words), len(table))
    env = clean_env(PATH=f"{pupper_bin.parent}{os.pathsep}{os.environ['PATH']}")
    from test_bad_input import GARBAGE_MJCF, NO_ACTUATOR_MJCF

    (tmp_path / "garbage.xml").write_text(GARBAGE_MJCF)
    (tmp_path / "noact.xml").write_text(NO_ACTUATOR_MJCF)
    wrong = []
    for cmd, message in rows:
        proc = shell(cmd, tmp_path, env)
        if proc.returncode != 2 or not matches(message.replace("…", "...") + "\n", proc.stdout):
            wrong.append(f"$ {cmd}\nexit {proc.returncode}\n--- shown\n{message}\n--- printed\n{proc.stdout}")
    assert not wrong, "\n\n".join(wrong)


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(REPO)) for p in PAGES])
def test_every_example_prints_what_the_page_shows(page: Path, tmp_path: Path, pupper_bin: Path):
    failures = check_page(page, tmp_path, pupper_bin)
    assert not failures, "\n\n".join(failures)


# -- the checker itself ------------------------------------------------------

SAMPLE = """intro
<!-- doc-test: skip needs a cluster -->
```sh
ray start --head
```

  ```console
  $ echo a \\
      b; echo 'run took 1.5 s in runs/20261125-014455-kp'
  a b
  ...
  $ exit 3
  [exit 3]
  ```
"""


def test_the_parser_reads_fences_notes_and_continuations():
    got = blocks(REPO / "README.md", SAMPLE)
    assert [(b.lang, b.note, b.line) for b in got] == [("sh", "skip needs a cluster", 3),
                                                      ("console", "", 7)]
    assert console_steps(got[1].body) == [("echo a \\\n    b; echo 'run took 1.5 s in runs/20261125-014455-kp'",
                                           "a b\n...\n", 0), ("exit 3", "", 3)]


def test_the_checker_fails_on_other_output_and_forgives_only_the_volatile():
    assert matches("16 cells in 1.04 s; wrote runs/20261125-014455-kp-kd/summary.csv\n",
                   "16 cells in 0.98 s; wrote runs/20261201-120000-kp-kd/summary.csv\n")
    assert not matches("16 cells in 1.04 s; wrote runs/x/summary.csv\n",
                       "15 cells in 1.04 s; wrote runs/x/summary.csv\n")
    assert not matches("final z 0.1198 m\n", "final z 0.1199 m\n")
    assert matches("a\n...\nz\n", "a\nb\nc\nz\n")


def test_a_wrong_example_is_reported(tmp_path: Path, pupper_bin: Path):
    page = tmp_path / "page.md"
    page.write_text("```console\n$ echo 2\n3\n```\n\n```python\n>>> 1 + 1\n3\n```\n\n"
                    "```text\n$ pupper sweep\n```\n\n<!-- doc-test: covered-by tests/nope.py -->\n"
                    "```sh\nmake sweep\n```\n")
    work = tmp_path / "w"
    work.mkdir()
    failures = check_page(page, work, pupper_bin)
    assert len(failures) == 4, failures
    assert "--- printed\n2\n" in failures[0] and "Expected:\n    3\nGot:\n    2" in failures[1]
    assert "a command in a text block" in failures[2] and "names no file" in failures[3]


if __name__ == "__main__":  # a page at a time, while writing it: python tests/test_docs.py docs/x.md
    import tempfile

    binary = Path(os.environ.get("PUPPER_BIN", REPO / "target" / "release" / "pupper"))
    for arg in sys.argv[1:]:
        with tempfile.TemporaryDirectory() as d:
            found = check_page(Path(arg).resolve(), Path(d), binary)
            print("\n\n".join(found) or f"{arg}: every example as shown")
