"""The documentation site's link checks, as the strict build (CI) applies them: a broken
relative link, or one to something that is not a page, fails the build."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _validation() -> str:
    """mkdocs.yml's ``validation:`` block, as written."""
    lines = (ROOT / "mkdocs.yml").read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("validation:"))
    end = next((i for i in range(start + 1, len(lines)) if lines[i] and not lines[i][0].isspace()), len(lines))
    return "\n".join(lines[start:end])


def _build(tmp_path: Path, page: str) -> subprocess.CompletedProcess:
    pytest.importorskip("mkdocs")
    (tmp_path / "docs" / "examples" / "plugin").mkdir(parents=True)
    (tmp_path / "docs" / "examples" / "plugin" / "plugin.py").write_text("x = 1\n")
    (tmp_path / "docs" / "other.md").write_text("# Other\n")
    (tmp_path / "docs" / "index.md").write_text(page)
    (tmp_path / "mkdocs.yml").write_text(f"site_name: links\nnav:\n  - index.md\n  - other.md\n{_validation()}\n")
    return subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_strict_build_passes_good_links(tmp_path):
    built = _build(tmp_path, "# Home\n\n[other](other.md), [a heading](other.md#other)\n")
    assert built.returncode == 0, built.stderr


@pytest.mark.parametrize(
    ("link", "named"),
    [("missing.md", "missing.md"), ("examples/plugin", "examples/plugin"), ("other.md#nowhere", "nowhere")],
    ids=["missing page", "a directory", "a missing anchor"],
)
def test_the_strict_build_fails_on_a_broken_link(tmp_path, link, named):
    built = _build(tmp_path, f"# Home\n\n[broken]({link}) and [other](other.md)\n")
    assert built.returncode != 0
    assert named in built.stderr
