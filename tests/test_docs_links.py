"""Every relative link in README.md and docs/*.md resolves to a file of the repository, and every anchor into
docs/physics.md (from a link, or from a code comment citing ``docs/physics.md#<anchor>``) exists."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path
from urllib.parse import unquote

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")  # [text](target "title")
REF_DEF = re.compile(r"^\s*\[[^\]]+\]:\s*(\S+)", re.M)  # [label]: target
ANCHOR_ID = re.compile(r"<a\s+(?:id|name)=\"([^\"]+)\"")
CITED = re.compile(r"docs/physics\.md#([A-Za-z0-9_-]+)")


def slug(heading: str) -> str:
    """GitHub's heading anchor: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    text = page.read_text()
    found = set(ANCHOR_ID.findall(text))
    found |= {slug(h) for h in re.findall(r"^#{1,6}\s+(.+?)\s*#*$", text, re.M)}
    return found


def links(page: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)  # code blocks are not links
    text = re.sub(r"`[^`]*`", "", text)
    return LINK.findall(text) + REF_DEF.findall(text)


def is_external(target: str) -> bool:
    return re.match(r"^[a-z][a-z0-9+.-]*:", target) is not None  # http:, https:, mailto:, ...


def test_link_parser_sees_links_and_skips_code():
    # control of the parser itself: two links, one image, one external, none from code
    page = REPO / "docs" / "_probe.md"
    text = (
        "[a](physics.md#frames) ![img](campbell.png) [w](https://example.org)\n```\n[x](nowhere.md)\n```\n`[y](no.md)`"
    )
    try:
        page.write_text(text)
        assert links(page) == ["physics.md#frames", "campbell.png", "https://example.org"]
    finally:
        page.unlink()


def test_physics_page_has_its_anchors():
    ids = anchors(REPO / "docs" / "physics.md")
    for name in ("frames", "fe", "formulations", "controller", "sampled", "floquet", "charts", "newmark"):
        assert name in ids
    assert slug("## 5. The formulations `derived` and `seed`".lstrip("# ")) == "5-the-formulations-derived-and-seed"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_relative_links_resolve(page):
    bad = []
    for target in links(page):
        if is_external(target):
            continue
        path, _, anchor = unquote(target).partition("#")
        dest = page if not path else (page.parent / path).resolve()
        if not dest.exists():
            bad.append(f"{target}: no file {dest.relative_to(REPO) if dest.is_relative_to(REPO) else dest}")
        elif not dest.is_relative_to(REPO):
            bad.append(f"{target}: outside the repository")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{target}: no anchor #{anchor} in {dest.relative_to(REPO)}")
    assert not bad, f"{page.relative_to(REPO)}: " + "; ".join(bad)


def test_cited_physics_anchors_exist():
    ids = anchors(REPO / "docs" / "physics.md")
    out = subprocess.run(
        ["git", "grep", "-n", "-E", r"docs/physics\.md#"], cwd=REPO, capture_output=True, text=True, check=False
    ).stdout
    assert out, "no citation of docs/physics.md found: the grep itself failed"
    bad = [line for line in out.splitlines() for name in CITED.findall(line) if name not in ids]
    assert not bad, "\n".join(bad)


def test_no_reference_to_files_outside_the_repository():
    # the specification files the project was written from are not shipped: cite docs/ instead.
    names = "|".join(f"{stem}\\.md" for stem in ("PHYSICS", "DESIGN", "ROS2-NOTES", "STYLE"))
    out = subprocess.run(["git", "grep", "-n", "-E", names, "--", "."], cwd=REPO, capture_output=True, text=True)
    assert out.returncode in (0, 1), out.stderr  # 1: nothing found
    assert out.stdout == "", out.stdout
