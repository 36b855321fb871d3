"""The test command itself: ``make test`` runs pytest on two workers with the VM test first.

The suite's wall time is dominated by the VM test (one qemu run under TCG, tests/test_kernel_vm.py);
``make test`` runs it on one pytest-xdist worker and everything else beside it on the
other. These tests check the pieces that make that so: the Makefile's command, the
test extra that installs pytest-xdist, the VM file collected first, and what a worker
says (the VM's figures) reaching the terminal summary.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _make_test_recipe() -> str:
    text = (REPO / "Makefile").read_text()
    m = re.search(r"^test:.*\n((?:\t.*\n)+)", text, re.M)
    assert m, "Makefile has no test target"
    return m.group(1)


def test_make_test_runs_two_workers_by_file() -> None:
    recipe = _make_test_recipe()
    assert "-m pytest -n $(PYTEST_WORKERS) --dist loadfile --no-loadscope-reorder" in recipe
    assert re.search(r"^PYTEST_WORKERS \?= 2$", (REPO / "Makefile").read_text(), re.M)


def test_the_test_extra_installs_pytest_xdist() -> None:
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    test_extra = pyproject["project"]["optional-dependencies"]["test"]
    assert any(r.startswith("pytest-xdist") for r in test_extra)
    addopts = pyproject["tool"]["pytest"]["ini_options"]["addopts"].split()
    assert "-ra" in addopts, "skips must still show (-ra)"


def test_the_vm_test_is_collected_first() -> None:
    res = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
         "tests/test_sdnotify.py", "tests/test_kernel_vm.py", "tests/test_buttons.py"],
        cwd=REPO, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert res.returncode == 0, res.stdout + res.stderr
    ids = [ln for ln in res.stdout.splitlines() if "::" in ln]
    n_vm = sum(ln.startswith("tests/test_kernel_vm.py::") for ln in ids)
    assert n_vm > 10 and all(ln.startswith("tests/test_kernel_vm.py::") for ln in ids[:n_vm])
    assert ids[n_vm].startswith("tests/test_sdnotify.py::")  # the rest keep their order


def test_a_workers_note_reaches_the_summary(tmp_path: Path) -> None:
    """What the VM fixture says on a worker (its wall time and figures) is printed by the
    controller at the end, once per note; the same in a serial run."""
    pytest.importorskip("xdist", reason="pytest-xdist is in the test extra (make setup)")
    shutil.copy(REPO / "tests" / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_note.py").write_text(
        "def test_one(say):\n    say('test VM: 12 s wall time (a note)')\n\n"
        "def test_two():\n    pass\n"
    )
    for workers in ("2", "0"):
        res = subprocess.run(
            [sys.executable, "-m", "pytest", "-n", workers, "--dist", "loadfile",
             "-p", "no:cacheprovider", "-q", "--rootdir", str(tmp_path), str(tmp_path)],
            cwd=tmp_path, capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert res.returncode == 0, res.stdout + res.stderr
        assert res.stdout.count("test VM: 12 s wall time (a note)") == 1, (workers, res.stdout)
        assert "2 passed" in res.stdout
