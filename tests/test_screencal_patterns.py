"""The three calibration patterns (dissertation Fig. 5.1) against their stated geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omnidev.screencal.patterns import black_pattern, dot_grid, dot_pattern, white_pattern


def test_white_and_black_fill_the_screen() -> None:
    w, b = white_pattern(1920, 1080), black_pattern(1920, 1080)
    assert w.shape == b.shape == (1080, 1920)
    assert w.dtype == b.dtype == np.uint8
    assert int(w.min()) == 255 and int(b.max()) == 0


@pytest.mark.parametrize(
    ("width", "height", "n"), [(1920, 1080, 9), (1280, 1024, 7), (800, 600, 5), (3840, 2160, 11)]
)
def test_dot_layout_cuts_the_screen_into_equal_cells(width: int, height: int, n: int) -> None:
    img, g = dot_pattern(width, height, n)
    assert img.shape == (height, width) and g.n == n and g.centers.shape == (n * n, 2)
    sx, sy = width / (n + 1), height / (n + 1)
    assert g.spacing_px == pytest.approx((sx, sy))
    grid = g.grid()
    # row-major from the top-left dot; the outer dots one spacing from the screen edge
    assert grid[0, 0] == pytest.approx((sx - 0.5, sy - 0.5))
    assert grid[0, 1] == pytest.approx((2 * sx - 0.5, sy - 0.5))
    assert grid[1, 0] == pytest.approx((sx - 0.5, 2 * sy - 0.5))
    assert grid[-1, -1] == pytest.approx((width - sx - 0.5, height - sy - 0.5))
    assert g.radius_px == pytest.approx(0.2 * min(sx, sy))
    assert g.polarity == "white"
    # each dot: grey-value centroid on its centre, area pi r^2, white on black
    worst, area_err = 0.0, 0.0
    r = g.radius_px
    for x, y in g.centers:
        r0, r1 = int(y - r) - 2, int(y + r) + 3
        c0, c1 = int(x - r) - 2, int(x + r) + 3
        win = img[r0:r1, c0:c1].astype(np.float64) / 255.0
        yy, xx = np.mgrid[r0:r1, c0:c1]
        cx, cy = (win * xx).sum() / win.sum(), (win * yy).sum() / win.sum()
        worst = max(worst, math.hypot(cx - x, cy - y))
        area_err = max(area_err, abs(win.sum() / (math.pi * r * r) - 1.0))
    assert worst < 2e-3, f"dot centroid off its centre by {worst:.4f} px"
    assert area_err < 0.01
    # nothing but the dots is lit
    total = img.astype(np.float64).sum() / 255.0
    assert total == pytest.approx(n * n * math.pi * r * r, rel=0.01)


def test_black_dots_on_white_is_the_negative() -> None:
    white_dots, g = dot_pattern(1280, 720, 9, 20.0)
    black_dots, g2 = dot_pattern(1280, 720, 9, 20.0, polarity="black")
    assert g2.polarity == "black" and np.array_equal(g.centers, g2.centers)
    assert np.array_equal(black_dots.astype(int), 255 - white_dots.astype(int))


def test_bad_layouts_are_refused() -> None:
    with pytest.raises(ValueError, match="half the spacing"):
        dot_grid(1920, 1080, 9, radius_px=60.0)
    with pytest.raises(ValueError, match="at least 2 x 2"):
        dot_grid(1920, 1080, 1)
    with pytest.raises(ValueError, match="at least 16x16"):
        white_pattern(8, 8)
