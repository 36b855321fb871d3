"""Screen mapping and the One Euro filter against closed-form truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omnidev.filters import OneEuroFilter, smoothing_factor
from omnidev.screen import ABS_MAX, ScreenMapping, ScreenRect, clamp01


def test_single_screen_corners_and_centre():
    m = ScreenMapping.single(1920, 1080)
    assert m.to_pixel(0, 0) == (0, 0)
    assert m.to_pixel(1, 1) == (1919, 1079)
    assert m.to_device(0, 0) == (0, 0)
    assert m.to_device(1, 1) == (ABS_MAX, ABS_MAX)
    assert m.to_device(0.5, 0.5) == (round(959.5 * ABS_MAX / 1919), round(539.5 * ABS_MAX / 1079))


def test_right_monitor_of_two():
    m = ScreenMapping(ScreenRect.parse("1920x1080+1920+0"), 3840, 1080)
    assert m.to_pixel(0, 0) == (1920, 0)
    assert m.to_pixel(1, 1) == (3839, 1079)
    dx, _ = m.to_device(0, 0)
    assert dx == round(1920 * ABS_MAX / 3839)
    assert m.to_device(1, 0)[0] == ABS_MAX


@pytest.mark.parametrize("v,want", [(-3.0, 0.0), (7.0, 1.0), (0.25, 0.25), (math.nan, 0.5)])
def test_clamp(v, want):
    assert clamp01(v) == want


def test_bad_rects():
    with pytest.raises(ValueError, match="WxH"):
        ScreenRect.parse("wide")
    with pytest.raises(ValueError, match="does not fit"):
        ScreenMapping(ScreenRect(1920, 0, 1920, 1080), 1920, 1080)


def test_one_euro_with_beta_zero_is_the_exponential_smoother():
    f = OneEuroFilter(min_cutoff=2.0, beta=0.0)
    dt = 1 / 60
    a = smoothing_factor(dt, 2.0)
    assert a == pytest.approx(1 / (1 + 1 / (2 * math.pi * 2.0 * dt)))
    y = f(0.0, [0.0])
    want = 0.0
    for i in range(1, 30):
        y = f(i * dt, [1.0])
        want = a * 1.0 + (1 - a) * want
        assert y[0] == pytest.approx(want, rel=1e-12)


def test_one_euro_steady_when_still_and_quick_when_moving():
    rng = np.random.default_rng(1)
    dt = 1 / 60
    f = OneEuroFilter(min_cutoff=1.0, beta=2.0)
    noise = 0.002
    still = [f(i * dt, [0.5 + rng.normal(0, noise)])[0] for i in range(240)]
    jitter = float(np.std(still[60:]))
    assert jitter < noise / 3  # steady hand: jitter cut by more than 3x
    # a fast sweep (1 screen width per second): lag at the end of a 0.5 s ramp
    f2 = OneEuroFilter(min_cutoff=1.0, beta=2.0)
    slow = OneEuroFilter(min_cutoff=1.0, beta=0.0)
    t = np.arange(0, 0.5, dt)
    xs = 0.2 + 1.0 * t
    out = [f2(ti, [xi])[0] for ti, xi in zip(t, xs, strict=True)]
    out_slow = [slow(ti, [xi])[0] for ti, xi in zip(t, xs, strict=True)]
    lag = xs[-1] - out[-1]
    assert lag < 0.2 * (xs[-1] - out_slow[-1])  # speed raises the cutoff: 5x less lag
    assert lag < 0.03  # under 3% of the screen after half a second at full speed


def test_one_euro_rejects_bad_parameters():
    with pytest.raises(ValueError, match="min_cutoff"):
        OneEuroFilter(min_cutoff=0)
    with pytest.raises(ValueError, match="beta"):
        OneEuroFilter(beta=-1)
