"""Every relative link and image in the README, the changelog and docs/ points at a file or folder that exists."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", ROOT / "CHANGELOG.md", *(ROOT / "docs").rglob("*.md")])
PARSER = MarkdownIt("commonmark").enable("table")


def link_targets(markdown: str) -> list[str]:
    """The targets of the links and images of a Markdown text, as written (code spans and blocks skipped)."""
    targets = []
    for token in PARSER.parse(markdown):
        for child in token.children or ():
            if child.type == "link_open":
                targets.append(str(child.attrGet("href")))
            elif child.type == "image":
                targets.append(str(child.attrGet("src")))
    return targets


def missing_targets(page: Path) -> list[str]:
    """The relative targets of ``page``'s links that name no existing path (anchors and URLs are not checked)."""
    missing = []
    for target in link_targets(page.read_text(encoding="utf-8")):
        parts = urlsplit(target)
        if parts.scheme or parts.netloc or not parts.path:
            continue
        if not (page.parent / unquote(parts.path)).exists():
            missing.append(target)
    return missing


def test_the_link_reader_finds_links_and_images_but_not_code(tmp_path):
    (tmp_path / "there.md").write_text("x")
    page = tmp_path / "page.md"
    page.write_text("[a](there.md#part) ![b](gone.png) [c](https://example.org/x)\n\n| t |\n|---|\n| [d](gone/) |\n\n"
                    "`[e](not-a-link.md)`\n\n```\n[f](in-a-block.md)\n```\n")
    assert link_targets(page.read_text()) == ["there.md#part", "gone.png", "https://example.org/x", "gone/"]
    assert missing_targets(page) == ["gone.png", "gone/"]


def test_the_pages_are_found():
    names = {page.relative_to(ROOT).as_posix() for page in PAGES}
    assert {"README.md", "CHANGELOG.md", "docs/training.md", "docs/experiments/README.md"} <= names


@pytest.mark.parametrize("page", PAGES, ids=lambda page: page.relative_to(ROOT).as_posix())
def test_every_relative_link_resolves(page):
    assert missing_targets(page) == []
