"""The Python examples of the README and of the user's pages run as written.

Every ```python block of README.md, docs/getting-started.md, docs/robots.md, docs/concepts/
and docs/guides/ runs in a fresh namespace, in a folder holding the TOML blocks of those
pages whose first line names their file (``# lean.toml: ...``) and the repository's
``tests`` folder (the robot files the pages name). The reference, results and
design pages quote code (contracts, measured snippets) and are not run here.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", ROOT / "docs" / "getting-started.md", ROOT / "docs" / "robots.md",
         *sorted((ROOT / "docs" / "concepts").glob("*.md")),
         *sorted((ROOT / "docs" / "guides").glob("*.md"))]
PAGES = [page for page in PAGES if page.exists()]


def _blocks(language: str, page: Path) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", page.read_text(), re.S | re.M)


BLOCKS = [(page.relative_to(ROOT).as_posix(), i, block)
          for page in PAGES for i, block in enumerate(_blocks("python", page))]
FILES = {m.group(1): m.group(0) for page in PAGES for m in
         (re.match(r"# (\S+\.toml)\b.*?(?=\Z)", b, re.S) for b in _blocks("toml", page)) if m}


def test_the_pages_have_their_examples():
    readme = [block for name, _, block in BLOCKS if name == "README.md"]
    assert len(readme) == 1 and "standing_controller" in readme[0]
    assert len(readme[0].strip().splitlines()) <= 11  # the controller in ten lines (+ import)
    started = [block for name, _, block in BLOCKS if name == "docs/getting-started.md"]
    for name in ("standing_controller", "add_task", "simulate", "Simulator", "solve",
                 "HQPError"):
        assert any(name in block for block in started), name
    assert any("run_behavior" in block for _, _, block in BLOCKS)
    assert "lean.toml" in FILES


@pytest.mark.slow
@pytest.mark.parametrize("page, index, block", BLOCKS,
                         ids=[f"{name}:{i + 1}" for name, i, _ in BLOCKS])
def test_an_example_runs(page, index, block, tmp_path, monkeypatch, capsys):
    for name, text in FILES.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "tests").symlink_to(ROOT / "tests")  # the robot files the pages name
    monkeypatch.chdir(tmp_path)
    exec(compile(block, f"{page} python block {index + 1}", "exec"), {"__name__": "__main__"})
    assert capsys.readouterr().out.strip()  # every example prints what it shows
