"""TSID's own Python environment: ``python -m hqp.bench.tsid_env`` creates it.

TSID (PyPI ``tsid``) cannot share hqp's environment: hqp pins ``pin==3.8.0`` (placo 0.10.2
pins it), TSID's wheels are built against other pinocchio releases (tsid 1.10 needs
pinocchio 4 and has no wheel for this platform; tsid 1.7.1, the newest with one, needs
pinocchio 3.4.0). So the controller suite drives TSID in a worker process
(:mod:`hqp.bench.tsid_worker`) run by this environment's interpreter.

The environment is a virtual environment under :func:`env_dir` (``$HQP_TSID_ENV``, else
``$XDG_CACHE_HOME/hqp/tsid-venv``, else ``~/.cache/hqp/tsid-venv``), made with the running
interpreter's ``venv`` and filled from PyPI with binary wheels only (:data:`REQUIREMENTS`),
about 150 MB and one minute. ``python -m hqp.bench.tsid_env --check`` only tells whether it
exists and imports TSID.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import venv
from pathlib import Path

REQUIREMENTS = (
    "tsid==1.7.1",
    "pin==3.4.0",
    "cmeel-urdfdom==4.0.1",
    "cmeel-tinyxml2==10.0.0",
    "numpy",
)
"""What the environment installs: tsid 1.7.1 and the pinocchio its wheel was built against
(3.4.0); ``cmeel-urdfdom`` 4.0.1 and ``cmeel-tinyxml2`` 10.0.0 because pip's own picks (6.0.0,
11.0.0) are not the libraries pinocchio 3.4 links (``import pinocchio`` fails)."""

CHECK = ("import pinocchio, tsid\n"
         "if not hasattr(tsid, 'RobotWrapper'):\n"
         "    from tsid import tsid_pywrap as tsid\n"
         "print(tsid.RobotWrapper.__name__)\n")
"""Program the environment must run for it to count as usable."""


def env_dir() -> Path:
    """Folder of TSID's environment (module docstring)."""
    explicit = os.environ.get("HQP_TSID_ENV")
    if explicit:
        return Path(explicit)
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "hqp" / "tsid-venv"


def env_python(folder: Path | None = None) -> Path:
    """Return the environment's interpreter (it may not exist)."""
    return (folder or env_dir()) / "bin" / "python"


def usable(folder: Path | None = None, timeout: float = 60.0) -> str | None:
    """Why the environment cannot run TSID (``None``: it can).

    Args:
        folder: Environment folder (default :func:`env_dir`).
        timeout: Longest wait for the check [s].

    """
    python = env_python(folder)
    if not python.is_file():
        return (f"no TSID environment at {python.parent.parent} "
                "(create it with: python -m hqp.bench.tsid_env)")
    try:
        done = subprocess.run([str(python), "-c", CHECK], capture_output=True, text=True,
                              timeout=timeout, cwd=str(python.parent), check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"TSID environment at {python.parent.parent} does not run: {exc}"
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        return f"TSID environment at {python.parent.parent} cannot import tsid: {last}"
    return None


def create(folder: Path | None = None, *, quiet: bool = False) -> Path:
    """Create (or complete) the environment and return its interpreter.

    Raises:
        RuntimeError: pip could not install :data:`REQUIREMENTS` (its output says why), or
            the result does not import TSID.

    """
    folder = folder or env_dir()
    python = env_python(folder)
    if not python.is_file():
        folder.parent.mkdir(parents=True, exist_ok=True)
        venv.EnvBuilder(with_pip=True, clear=False).create(folder)
    cmd = [str(python), "-m", "pip", "install", "--only-binary=:all:", *REQUIREMENTS]
    if quiet:
        cmd.insert(4, "-q")
    done = subprocess.run(cmd, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"pip install into {folder} failed (exit {done.returncode})")
    reason = usable(folder)
    if reason is not None:
        raise RuntimeError(reason)
    return python


def main(argv: list[str] | None = None) -> int:
    """``python -m hqp.bench.tsid_env [--check] [--dir DIR]``."""
    parser = argparse.ArgumentParser(prog="python -m hqp.bench.tsid_env", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--check", action="store_true", help="only tell whether it is usable")
    parser.add_argument("--dir", type=Path, help=f"environment folder (default {env_dir()})")
    args = parser.parse_args(argv)
    if args.check:
        reason = usable(args.dir)
        print(reason or f"usable: {env_python(args.dir)}")
        return 0 if reason is None else 1
    try:
        python = create(args.dir)
    except RuntimeError as exc:
        print(f"hqp.bench.tsid_env: {exc}", file=sys.stderr)
        return 1
    print(python)
    return 0


if __name__ == "__main__":
    sys.exit(main())
