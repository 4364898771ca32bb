"""No dead relative link in the README or docs/: every `[text](path)` that
is not a web address names a file of the repository (anchors aside)."""

from __future__ import annotations

import re

from conftest import REPO

PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def links(text: str) -> list[str]:
    # links inside code blocks are examples, not links
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    return LINK.findall(text)


def test_the_checker_finds_a_dead_link():
    assert links("see [a](docs/a.md) and [b](https://x.org) `[c](d)`\n```\n[e](f)\n```") == [
        "docs/a.md", "https://x.org", "d"]


def test_no_dead_relative_link():
    dead = []
    for page in PAGES:
        for target in links(page.read_text()):
            if re.match(r"^[a-z]+:", target) or target.startswith("#"):
                continue
            path = target.split("#", 1)[0]
            if not (page.parent / path).exists():
                dead.append(f"{page.relative_to(REPO)}: {target}")
    assert dead == [], dead
