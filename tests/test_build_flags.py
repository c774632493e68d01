"""The vector flags of the core's build reach only translation units free of pinocchio.

A pinocchio translation unit built with AVX (or ``-march=native``) segfaults at teardown
(CMakeLists.txt). The AVX2/FMA flags are given to the solver's static library alone; this
reads CMakeLists.txt and the sources (nothing is compiled) and checks that every unit of
that library, through every project header it includes, never includes pinocchio, and that
no other target receives vector or native-architecture flags.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "hqp" / "_core" / "src"
CMAKE = (ROOT / "CMakeLists.txt").read_text()
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]', re.M)
VECTOR_FLAG = re.compile(r"-m(avx|fma|sse4|arch|tune)")


def _solver_sources() -> list[Path]:
    block = re.search(r"set\(HQP_SOLVER_SOURCES(.*?)\)", CMAKE, re.S)
    assert block, "CMakeLists.txt: no HQP_SOLVER_SOURCES"
    return [SRC / p for p in re.findall(r"\$\{HQP_SRC\}/(\S+\.cpp)", block.group(1))]


def _includes(path: Path, seen: set[Path]) -> set[str]:
    """Every file name included by ``path`` and by the project headers it includes."""
    names: set[str] = set()
    for name in INCLUDE.findall(path.read_text()):
        names.add(name)
        header = SRC / name
        if header.is_file() and header not in seen:
            seen.add(header)
            names |= _includes(header, seen)
    return names


def test_the_solver_units_include_no_pinocchio() -> None:
    sources = _solver_sources()
    assert len(sources) >= 5 and all(p.is_file() for p in sources), sources
    for source in sources:
        names = _includes(source, set())
        assert not [n for n in names if "pinocchio" in n], (source, sorted(names))


def test_the_include_reader_sees_pinocchio_where_it_is() -> None:
    # the reader itself: the model's unit does include pinocchio through its header
    assert any("pinocchio" in n for n in _includes(SRC / "model" / "robot.cpp", set()))


def test_only_the_solver_library_gets_vector_flags() -> None:
    flagged = [line.strip() for line in CMAKE.splitlines()
               if VECTOR_FLAG.search(line) and not line.lstrip().startswith("#")]
    assert flagged, "no vector flags found: the test no longer reads the build"
    body = re.search(r"function\(hqp_solver_library name\)(.*?)endfunction\(\)", CMAKE, re.S)
    assert body, "CMakeLists.txt: no hqp_solver_library function"
    for line in flagged:
        # the compile check of the machine, or the solver library's own options
        assert "CMAKE_REQUIRED_FLAGS" in line or line in body.group(1), line
    assert "CMAKE_CXX_FLAGS" not in CMAKE.replace("CMAKE_CXX_FLAGS_", "")
