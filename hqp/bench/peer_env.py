"""The peers' own Python environments: ``python -m hqp.bench.peer_env {placo,tsid}`` makes one.

PlaCo and TSID cannot share hqp's environment: hqp is built on pinocchio 4 (``pin>=4.1``),
``placo==0.10.2`` pins ``pin==3.8.0``, and TSID's newest wheel for this platform (tsid 1.7.1;
tsid 1.10 needs ``libtsid`` 1.10, an sdist to compile) was built against ``pin==3.4.0``. So
each peer runs in a virtual environment of its own, driven as a worker process
(:mod:`hqp.bench.worker`; the scripts :mod:`hqp.bench.placo_worker` and
:mod:`hqp.bench.tsid_worker` import nothing of hqp).

A peer's environment is a virtual environment under :func:`env_dir` (``$HQP_PLACO_ENV`` /
``$HQP_TSID_ENV``, else ``$XDG_CACHE_HOME/hqp/<peer>-venv``, else
``~/.cache/hqp/<peer>-venv``), made with the running interpreter's ``venv`` and filled from
PyPI with binary wheels only (:attr:`Peer.requirements`). ``--check`` only tells whether it
exists and imports the peer; ``--quiet`` keeps pip quiet.

``hqp compare`` makes PlaCo's environment itself the first time it runs PlaCo (:func:`ensure`),
unless ``HQP_NO_PEER_INSTALL=1`` is set.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import venv
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from hqp.errors import HQPError, UnknownName


@dataclass(frozen=True)
class Peer:
    """What a peer's environment holds and how it is checked.

    Attributes:
        name: The peer's name (``placo``, ``tsid``): the command's argument, the folder's prefix.
        title: How messages name it.
        requirements: What pip installs (binary wheels only).
        check: Program the environment must run for it to count as usable.

    """

    name: str
    title: str
    requirements: tuple[str, ...]
    check: str

    @property
    def variable(self) -> str:
        """Environment variable that overrides the folder (``HQP_PLACO_ENV``)."""
        return f"HQP_{self.name.upper()}_ENV"

    @property
    def command(self) -> str:
        """The command that makes the environment."""
        return f"python -m hqp.bench.peer_env {self.name}"


PEERS: dict[str, Peer] = {
    "placo": Peer(
        name="placo",
        title="PlaCo",
        # pip's own pick of cmeel-urdfdom for pin 3.8.0 (6.0.0) is not the library it links
        requirements=("placo==0.10.2", "pin==3.8.0", "cmeel-urdfdom==4.0.1", "numpy"),
        check="import pinocchio, placo\nprint(placo.DynamicsSolver.__name__)\n",
    ),
    "tsid": Peer(
        name="tsid",
        title="TSID",
        # tsid 1.7.1 and the pinocchio its wheel was built against (3.4.0); cmeel-urdfdom
        # 4.0.1 and cmeel-tinyxml2 10.0.0 because pip's own picks (6.0.0, 11.0.0) are not the
        # libraries pinocchio 3.4 links (`import pinocchio` fails)
        requirements=("tsid==1.7.1", "pin==3.4.0", "cmeel-urdfdom==4.0.1",
                      "cmeel-tinyxml2==10.0.0", "numpy"),
        check=("import pinocchio, tsid\n"
               "if not hasattr(tsid, 'RobotWrapper'):\n"
               "    from tsid import tsid_pywrap as tsid\n"
               "print(tsid.RobotWrapper.__name__)\n"),
    ),
}
"""The peers that run in environments of their own."""

NO_INSTALL = "HQP_NO_PEER_INSTALL"
"""Set to ``1``: :func:`ensure` never installs (the peer is skipped and the message says how
to add it)."""


class PeerUnavailable(HQPError):
    """A peer's environment is missing or broken (the message says how to make it)."""


def peer(name: str) -> Peer:
    """Return the peer called ``name``.

    Raises:
        UnknownName: Not a peer of :data:`PEERS` (the message lists them).

    """
    if name not in PEERS:
        raise UnknownName("peer", name, tuple(PEERS))
    return PEERS[name]


def env_dir(name: str) -> Path:
    """Folder of a peer's environment (module docstring)."""
    p = peer(name)
    explicit = os.environ.get(p.variable)
    if explicit:
        return Path(explicit)
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "hqp" / f"{p.name}-venv"


def env_python(name: str, folder: Path | None = None) -> Path:
    """Return the interpreter of a peer's environment (it may not exist)."""
    return (folder or env_dir(name)) / "bin" / "python"


def usable(name: str, folder: Path | None = None, timeout: float = 60.0) -> str | None:
    """Why a peer's environment cannot run the peer (``None``: it can).

    Args:
        name: The peer (``placo``, ``tsid``).
        folder: Environment folder (default :func:`env_dir`).
        timeout: Longest wait for the check [s].

    """
    p = peer(name)
    python = env_python(name, folder)
    where = python.parent.parent
    if not python.is_file():
        return f"no {p.title} environment at {where} (create it with: {p.command})"
    try:
        done = subprocess.run([str(python), "-I", "-c", p.check], capture_output=True,
                              text=True, timeout=timeout, cwd=str(python.parent), check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"{p.title} environment at {where} does not run: {exc} (re-create it with: " \
               f"{p.command})"
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        return (f"{p.title} environment at {where} cannot import {p.name}: {last} "
                f"(re-create it with: {p.command})")
    return None


def create(name: str, folder: Path | None = None, *, quiet: bool = False) -> Path:
    """Create (or complete) a peer's environment and return its interpreter.

    Args:
        name: The peer (``placo``, ``tsid``).
        folder: Environment folder (default :func:`env_dir`).
        quiet: Capture pip's output (its last line goes into the error when it fails).

    Raises:
        PeerUnavailable: pip could not install the requirements (offline, no wheel), or the
            result does not import the peer.

    """
    p = peer(name)
    folder = folder or env_dir(name)
    python = env_python(name, folder)
    if not python.is_file():
        folder.parent.mkdir(parents=True, exist_ok=True)
        venv.EnvBuilder(with_pip=True, clear=False).create(folder)
    cmd = [str(python), "-m", "pip", "install", "--disable-pip-version-check",
           "--only-binary=:all:", *p.requirements]
    if quiet:
        cmd.insert(4, "-q")
    done = subprocess.run(cmd, check=False, capture_output=quiet, text=True)
    if done.returncode != 0:
        last = (done.stderr or "").strip().splitlines() if quiet else []
        why = f": {last[-1]}" if last else ""
        raise PeerUnavailable(f"pip install of {p.title} into {folder} failed "
                              f"(exit {done.returncode}){why}")
    reason = usable(name, folder)
    if reason is not None:
        raise PeerUnavailable(reason)
    return python


def ensure(name: str, notice: TextIO | None = None) -> str | None:
    """Make a peer's environment if it is not usable; return why it is still not (``None``: ok).

    Installs unless :data:`NO_INSTALL` is ``1``. While it installs, one line goes to
    ``notice``: what it makes, where, and how long it took.

    Args:
        name: The peer (``placo``, ``tsid``).
        notice: Stream of the one-line notice (default: stderr).

    """
    p = peer(name)
    reason = usable(name)
    if reason is None:
        return None
    if os.environ.get(NO_INSTALL, "") not in ("", "0"):
        return f"{reason}; not made because {NO_INSTALL} is set"
    out = notice or sys.stderr
    folder = env_dir(name)
    out.write(f"hqp: making {p.title}'s environment once in {folder} (pip, binary wheels; "
              f"{NO_INSTALL}=1 skips this) ... ")
    out.flush()
    start = time.perf_counter()
    try:
        create(name, folder, quiet=True)
    except (PeerUnavailable, OSError) as exc:
        out.write(f"failed after {time.perf_counter() - start:.0f} s\n")
        out.flush()
        return f"{exc} (add it with: {p.command})"
    out.write(f"done in {time.perf_counter() - start:.0f} s\n")
    out.flush()
    return None


def main(argv: list[str] | None = None) -> int:
    """``python -m hqp.bench.peer_env {placo,tsid} [--check] [--dir DIR] [--quiet]``."""
    parser = argparse.ArgumentParser(prog="python -m hqp.bench.peer_env", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("peer", choices=sorted(PEERS), help="the peer whose environment to make")
    parser.add_argument("--check", action="store_true", help="only tell whether it is usable")
    parser.add_argument("--dir", type=Path,
                        help="environment folder (default: $HQP_<PEER>_ENV, else the user cache)")
    parser.add_argument("--quiet", action="store_true", help="keep pip quiet")
    args = parser.parse_args(argv)
    if args.check:
        reason = usable(args.peer, args.dir)
        print(reason or f"usable: {env_python(args.peer, args.dir)}")
        return 0 if reason is None else 1
    try:
        python = create(args.peer, args.dir, quiet=args.quiet)
    except PeerUnavailable as exc:
        print(f"hqp.bench.peer_env: {exc}", file=sys.stderr)
        return 1
    print(python)
    return 0


if __name__ == "__main__":
    sys.exit(main())
