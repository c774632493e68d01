"""The documentation builds, its links hold, its commands run, and it tells no history.

- ``mkdocs build --strict`` passes without a warning (broken links and anchors, pages left
  out of the navigation, docstrings mkdocstrings cannot read are warnings: mkdocs.yml);
- every relative link of the README names a file of the repository;
- every ``hqp ...`` command of a ```bash (or ```sh) block of the README,
  docs/getting-started.md, docs/robots.md, docs/concepts/ and docs/guides/ exits with status
  0, run from a folder holding the pages' TOML files and the repository's ``tests`` folder
  (the robot files the pages name); the commands that are not run are listed in ``NOT_RUN``
  with the reason;
- no tracked text file speaks of a "session" followed by a number (the project's working
  sessions are no fact a user can use: state the fact, or the measurement with its command).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", ROOT / "docs" / "getting-started.md", ROOT / "docs" / "robots.md",
         *sorted((ROOT / "docs" / "concepts").glob("*.md")),
         *sorted((ROOT / "docs" / "guides").glob("*.md"))]


def _env() -> dict[str, str]:
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1", OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1", MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def test_the_documentation_builds_strictly_without_a_warning(tmp_path):
    pytest.importorskip("mkdocs", reason="the test extra holds mkdocs-material and mkdocstrings")
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
         "-d", str(tmp_path / "site")],
        cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=600)
    output = result.stdout + result.stderr
    assert result.returncode == 0, output
    assert "WARNING" not in output, output
    assert (tmp_path / "site" / "reference" / "cli" / "index.html").exists()
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    for command in ("hqp compare", "hqp run", "hqp bench", "hqp view", "hqp sweep"):
        assert command in cli, command  # generated from the parser
    api = (tmp_path / "site" / "reference" / "api" / "solver" / "index.html").read_text()
    assert "final_metric" in api  # mkdocstrings rendered the docstrings


def test_the_readme_links_name_files_of_the_repository():
    text = (ROOT / "README.md").read_text()
    targets = [t.split("#")[0] for t in re.findall(r"\]\(([^)\s]+)\)", text)
               if "://" not in t and not t.startswith("#")]
    assert targets
    missing = [t for t in targets if not (ROOT / t).exists()]
    assert not missing, missing


def test_the_readme_is_one_screen_with_its_two_commands():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 150
    bash = re.findall(r"^```bash\n(.*?)^```", text, re.S | re.M)
    assert bash[:2] == [
        "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && "
        "hqp compare hand-reach\n",
        "python3 -m venv .venv && . .venv/bin/activate && pip install -e \".[test]\" && "
        "python -m pytest -q\n"]


# ---------------------------------------------------------------------------------------------
# The commands of the pages

NOT_RUN = {
    "hqp view": "a server that runs until stopped: tests/test_view.py drives it in a browser",
    "hqp sweep push-map": "a study of hundreds of simulations (minutes on 2 cores): "
                          "tests/test_study_ray.py runs a small push map",
    "hqp sweep grid": "18 simulations of 5 s: tests/test_study_ray.py runs a tiny grid",
    "hqp sweep study.toml": "needs the user's study file",
    "hqp bench --suite controller": "about 100 s (every backend on three robots): "
                                    "tests/test_bench_suites.py runs the suite on a subset",
    "hqp bench --suite recorded": "minutes: tests/test_bench_suites.py runs the suite on a subset",
    "hqp bench --suite all": "minutes: the three suites above",
}
"""Command prefixes not run here, and why."""

def _commands() -> list[tuple[str, str]]:
    commands = []
    for page in PAGES:
        for block in re.findall(r"^```(?:bash|sh)\n(.*?)^```", page.read_text(), re.S | re.M):
            for line in block.replace("\\\n", " ").splitlines():
                command = re.split(r"\s+#\s", line)[0].strip()
                if command.startswith("hqp ") or command.startswith("OMP_NUM_THREADS=1 hqp "):
                    commands.append((page.relative_to(ROOT).as_posix(), command))
    return commands


COMMANDS = _commands()


def test_the_pages_show_commands():
    assert len(COMMANDS) >= 15
    assert all(any(c.startswith(p) for _, c in COMMANDS) for p in NOT_RUN), \
        "a NOT_RUN entry no page shows any more"


def _toml_files(folder: Path) -> None:
    for page in PAGES:
        for block in re.findall(r"^```toml\n(.*?)^```", page.read_text(), re.S | re.M):
            match = re.match(r"# (\S+\.toml)\b", block)
            if match:
                (folder / match.group(1)).write_text(block)


FAST = ("hqp behaviors", "hqp bench --suite solver --quick")


@pytest.mark.parametrize(
    "page, command",
    [pytest.param(p, c, marks=() if c.startswith(FAST) else pytest.mark.slow) for p, c in COMMANDS],
    ids=[c for _, c in COMMANDS])
def test_a_command_of_the_pages_exits_0(page, command, tmp_path):
    skip = next((why for prefix, why in NOT_RUN.items() if command.startswith(prefix)), None)
    if skip:
        pytest.skip(f"not run: {skip}")
    _toml_files(tmp_path)
    (tmp_path / "tests").symlink_to(ROOT / "tests")  # tests/data/robots/*.toml
    argv = shlex.split(command.replace("OMP_NUM_THREADS=1 ", ""))
    hqp = [sys.executable, "-m", "hqp.cli"]
    result = subprocess.run(hqp + argv[1:], cwd=tmp_path, env=_env(), capture_output=True,
                            text=True, timeout=900)
    assert result.returncode == 0, f"{page}: {command}\n{result.stderr[-3000:]}"
    assert result.stdout.strip() or any(tmp_path.iterdir())


# ---------------------------------------------------------------------------------------------
# No history

_SESSION = re.compile(r"\b" + "sess" + r"ions?\s+\d", re.I)


def test_no_tracked_file_speaks_of_numbered_sessions():
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    names = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                           check=True).stdout.decode().split("\0")
    found = []
    for name in filter(None, names):
        path = ROOT / name
        if not path.is_file():
            continue
        data = path.read_bytes()
        if b"\0" in data[:8192]:
            continue  # binary
        for number, line in enumerate(data.decode("utf-8", "replace").splitlines(), 1):
            if _SESSION.search(line):
                found.append(f"{name}:{number}: {line.strip()[:100]}")
    assert not found, "\n".join(found)
