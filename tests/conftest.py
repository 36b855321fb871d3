"""Shared test helpers."""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("OMNIDEV_SHARED", REPO.parent / "shared"))
REALDATA = SHARED / "realdata"


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """PSNR in dB of two uint8 images over ``mask`` (all pixels if None)."""
    d = a.astype(np.float64) - b.astype(np.float64)
    if d.ndim == 3:
        d = d.reshape(d.shape[0], d.shape[1], -1)
        m = np.ones(d.shape[:2], bool) if mask is None else mask
        mse = float(np.mean(d[m] ** 2))
    else:
        m = np.ones(d.shape, bool) if mask is None else mask
        mse = float(np.mean(d[m] ** 2))
    return math.inf if mse == 0 else 10 * math.log10(255.0**2 / mse)


@pytest.fixture
def realdata() -> Path:
    if not REALDATA.is_dir():
        pytest.skip(f"real data not available: {REALDATA} is absent (it comes with ../shared)")
    return REALDATA


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--fuzz-full",
        action="store_true",
        help="tests/fuzz: draw many more random mutations per input format",
    )


# --- running on several workers (``make test`` runs ``pytest -n 2 --dist loadfile``) ---

_NOTES = pytest.StashKey[list[str]]()
"""Lines for the terminal summary: said on a worker, shown by the controller."""
_FUZZ = pytest.StashKey[list[str]]()
"""The fuzz suite's counts by command, from the worker that ran it."""


def _say(config: pytest.Config, text: str) -> None:
    """Show ``text`` past pytest's output capture: now in a serial run; in the terminal
    summary of a pytest-xdist run (a worker's own output is not shown)."""
    if hasattr(config, "workerinput"):
        config.stash.setdefault(_NOTES, []).append(text)
        return
    capman = config.pluginmanager.getplugin("capturemanager")
    if capman is not None:
        with capman.global_and_fixture_disabled():
            print(text, flush=True)
    else:
        print(text, flush=True)


@pytest.fixture(scope="session")
def say(request: pytest.FixtureRequest) -> Callable[[str], None]:
    """``say(text)``: show ``text`` past the output capture, also under pytest-xdist.

    A fixture (not an import) so that it is this conftest's copy whose notes the
    controller collects (pytest imports the conftest as ``conftest``)."""
    return lambda text: _say(request.config, text)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The VM test (marker ``vm``, one qemu run of many minutes) first: under
    ``pytest -n 2 --dist loadfile --no-loadscope-reorder`` its file is the first work
    unit, so it starts at once and the other worker runs the rest beside it."""
    items[:] = sorted(items, key=lambda it: it.get_closest_marker("vm") is None)  # stable


def _fuzz_text() -> str:
    import sys

    text = ""
    for name in ("tests.fuzz.test_fuzz", "fuzz.test_fuzz"):  # as pytest named it
        mod = sys.modules.get(name)
        if mod is not None:
            text = text or mod.pytest_terminal_summary_text()
    return text


def pytest_sessionfinish(session: pytest.Session) -> None:
    """On an xdist worker: hand the notes and the fuzz counts to the controller."""
    config = session.config
    if hasattr(config, "workeroutput"):
        config.workeroutput["omnidev_notes"] = config.stash.get(_NOTES, [])
        config.workeroutput["omnidev_fuzz"] = _fuzz_text()


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node: Any, error: object) -> None:  # xdist's hook, on the controller
    out = getattr(node, "workeroutput", None) or {}
    node.config.stash.setdefault(_NOTES, []).extend(out.get("omnidev_notes", []))
    if out.get("omnidev_fuzz"):
        node.config.stash.setdefault(_FUZZ, []).append(out["omnidev_fuzz"])


def pytest_terminal_summary(
    terminalreporter: pytest.TerminalReporter, exitstatus: int, config: pytest.Config
) -> None:
    """The fuzz suite's counts by command (tests/fuzz), when it ran; what workers said."""
    notes = config.stash.get(_NOTES, [])
    if notes:
        terminalreporter.section("said on the workers")
        for text in notes:
            terminalreporter.write_line(text.strip("\n"))
    fuzz: list[str] = config.stash.get(_FUZZ, [])
    text = "\n".join(fuzz) or _fuzz_text()
    if text:
        terminalreporter.section("fuzz suite: outcomes by command")
        terminalreporter.write_line(text)
