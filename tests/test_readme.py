"""The README's Python examples run as written (issue 19).

Every ```python block of README.md runs in a fresh namespace, in a folder holding the README's
TOML blocks whose first line names their file (``# lean.toml: ...``).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
TEXT = README.read_text()
BLOCKS = re.findall(r"^```python\n(.*?)^```", TEXT, re.S | re.M)
FILES = {m.group(1): m.group(0) for m in
         (re.match(r"# (\S+\.toml)\b.*?(?=\Z)", b, re.S)
          for b in re.findall(r"^```toml\n(.*?)^```", TEXT, re.S | re.M)) if m}


def test_the_readme_has_its_examples():
    assert len(BLOCKS) >= 5 and "lean.toml" in FILES
    for name in ("standing_controller", "add_task", "simulate", "Simulator", "run_behavior"):
        assert any(name in block for block in BLOCKS), name


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_a_readme_example_runs(index, tmp_path, monkeypatch, capsys):
    for name, text in FILES.items():
        (tmp_path / name).write_text(text)
    monkeypatch.chdir(tmp_path)
    exec(compile(BLOCKS[index], f"README.md python block {index + 1}", "exec"), {})
    assert capsys.readouterr().out.strip()  # every example prints what it shows
