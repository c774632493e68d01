"""example-robot-data: where its files are.

The bundled robots ``g1`` (Unitree G1, 29 DoF) and ``talos`` (PAL Robotics TALOS, 32 DoF)
are robot TOML files (``hqp/robots/data/g1.toml``, ``talos.toml``) whose URDFs are
``package://example-robot-data/robots/...`` paths; :func:`hqp.robots.from_urdf` builds them
like any user's humanoid. The installed example-robot-data ships no Python module: its files
live under ``<site-packages>/cmeel.prefix/share/example-robot-data/robots/`` (set
``EXAMPLE_ROBOT_DATA_SHARE`` to the ``share`` directory to override).
"""

from __future__ import annotations

from pathlib import Path

from hqp.robots.urdf import cache_dir, erd_share_dir


def erd_robots_dir() -> Path:
    """``.../share/example-robot-data/robots``."""
    return erd_share_dir() / "example-robot-data" / "robots"


__all__ = ["cache_dir", "erd_robots_dir", "erd_share_dir"]
