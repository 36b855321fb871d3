"""Shared test helpers."""

from __future__ import annotations

import math
import os
from pathlib import Path

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


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    """The fuzz suite's counts by command (tests/fuzz), when it ran."""
    import sys

    text = ""
    for name in ("tests.fuzz.test_fuzz", "fuzz.test_fuzz"):  # as pytest named it
        mod = sys.modules.get(name)
        if mod is not None:
            text = text or mod.pytest_terminal_summary_text()
    if text:
        terminalreporter.section("fuzz suite: outcomes by command")
        terminalreporter.write_line(text)
