"""The user's pages stay what issue 35 made them: short, with working links, and a README whose
Python example runs and whose first commands are the two a fresh machine needs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted((ROOT / "docs").glob("*.md"))]
#: A Markdown link or image to a relative path: ``[text](path)`` or ``![alt](path)``, anchors dropped.
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def fenced_blocks(text: str, language: str = "") -> list[str]:
    """The fenced code blocks of a Markdown text, of one language (``""``: untagged)."""
    return re.findall(rf"^```{language}\n(.*?)^```$", text, flags=re.M | re.S)


@pytest.mark.parametrize(("page", "most"), [("README.md", 350), ("BENCHMARKS.md", 1200)])
def test_pages_stay_short(page, most):
    lines = (ROOT / page).read_text(encoding="utf-8").count("\n")
    assert lines < most, f"{page} has {lines} lines: figures of past versions belong in docs/history.md"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_resolve(page):
    text = page.read_text(encoding="utf-8")
    targets = [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t)]
    missing = [t for t in targets if not (page.parent / t).exists()]
    assert not missing, f"{page.name} links to missing files: {missing}"


def test_readme_starts_with_the_fresh_machine_commands():
    blocks = fenced_blocks((ROOT / "README.md").read_text(encoding="utf-8"))
    assert [b.strip() for b in blocks[:2]] == [
        "pip install . && bandelets demo",
        "pip install '.[test]' && python -m pytest",
    ]


def test_readme_python_example_runs(capsys):
    (example,) = fenced_blocks((ROOT / "README.md").read_text(encoding="utf-8"), "python")
    exec(compile(example, "README.md", "exec"), {})
    printed = capsys.readouterr().out
    bpp, psnr = re.match(r"([\d.]+) bpp, ([\d.]+) dB", printed).groups()
    assert 0.47 <= float(bpp) <= 0.5  # a --bpp target lands within 3 % below it
    assert float(psnr) > 30
