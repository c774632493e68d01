"""The names a user starts from: ``hqp.<name>`` (imported on first use) and the old paths."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import hqp


@pytest.mark.parametrize("name", sorted(hqp._LAZY))
def test_top_level_names_are_the_library_objects(name):
    module, attribute = hqp._LAZY[name]
    expected = importlib.import_module(module)
    if attribute is not None:
        expected = getattr(expected, attribute)
    assert getattr(hqp, name) is expected
    assert name in hqp.__all__


def test_unknown_top_level_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        hqp.nope  # noqa: B018


def test_import_hqp_stays_light():
    """``import hqp`` loads neither MuJoCo nor pinocchio (they come with the names)."""
    code = "import sys, hqp; print('mujoco' in sys.modules, 'pinocchio' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


@pytest.mark.parametrize("path, name", [
    ("hqp.robots", "load"), ("hqp.controller", "standing_controller"), ("hqp.sim", "simulate"),
    ("hqp.sim", "Simulator"), ("hqp.sim", "Push"), ("hqp.sim", "Event"),
    ("hqp.tasks.position", "PositionTask"), ("hqp.solver", "Level"), ("hqp.solver", "solve"),
    ("hqp.cli", "main"), ("hqp.app.cli", "main"),
    ("hqp.model", "RobotModel"), ("hqp.model", "RobotState"), ("hqp.layout", "Layout"),
    ("hqp.layout", "ContactType"), ("hqp.world", "World"), ("hqp.geometry", "monotone_chain"),
])
def test_public_import_paths_keep_working(path, name):
    assert callable(getattr(importlib.import_module(path), name))
