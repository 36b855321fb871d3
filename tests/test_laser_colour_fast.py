"""The colour laser detector's fast path against its reference: the detector as it was
before its speed work (tests/laser_colour_reference.py, unchanged) on rendered laser
scenes, frame by frame: the same frames with a spot, the same spot within 0.1 px.

Scenes: the bench's 1280x720 laser video (omnidev.sim.screen.laser_video, k1 -0.25,
slides changing, frames without a spot) and randomized laser scenes of
omnidev.sim.laser_scenes (seeds 700004, 700018, 700024, 700037: the test sample of
tests/test_laser_colour.py, red and green, dark / white / saturated slides).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from omnidev.laser.colour_spot import ColourSpotDetector, _median, _sample, _upper_mean
from omnidev.sim.laser_scenes import LaserScene, screen_mask
from omnidev.sim.screen import laser_video, screen_rig
from tests.laser_colour_reference import ColourSpotDetector as Reference

# the fast path with the options that did not exist in the reference at their "off"
# values, and its defaults where they changed (the speed work changed no result;
# busy_confirm, min_rise, fringe_ratio, hold_spot, peak_margin, position "beam",
# new_margin 20, bright_rise and search_first came after it)
AS_REFERENCE: dict[str, object] = {
    "busy_confirm": 1,
    "peak_margin": 255,
    "new_margin": 30,
    "min_rise": 0.0,
    "fringe_ratio": 0.0,
    "hold_spot": False,
    "position": "centroid",
    "bright_rise": 0,
    "search_first": False,
}


def _compare(frames: list[np.ndarray], colour: str, mask: np.ndarray | None) -> tuple[int, int]:
    fast = ColourSpotDetector(colour, mask, **AS_REFERENCE)  # type: ignore[arg-type]
    ref = Reference(colour, mask)
    found = 0
    for i, img in enumerate(frames):
        a, b = fast.detect(img), ref.detect(img)
        assert (a is None) == (b is None), f"frame {i}: fast {a}, reference {b}"
        if a is not None and b is not None:
            found += 1
            assert math.hypot(a.u - b.u, a.v - b.v) <= 0.1, f"frame {i}: {a} vs {b}"
            assert a.area == b.area and a.colour == b.colour
            assert a.score == pytest.approx(b.score)
    assert fast.slide_changes == ref.slide_changes and fast.refused == ref.refused
    return found, len(frames)


def test_bench_video_same_spots() -> None:
    rig = screen_rig((1280, 720), -0.25)
    frames = [img for img, _, _ in laser_video(rig, 40, colour="red", seed=0)]
    found, n = _compare(frames, "red", None)
    assert found >= 15 and n == 40  # not vacuous: measured 17 of 40 frames with a spot


@pytest.mark.parametrize("seed", [700004, 700018, 700024, 700037])
def test_laser_scenes_same_spots(seed: int) -> None:
    sc = LaserScene(seed, frames=30)
    frames = [img for img, _ in sc.frames()]
    found, _ = _compare(frames, sc.laser.colour, screen_mask(sc.scene))
    assert found >= 3


@pytest.mark.parametrize(("h", "w"), [(720, 1280), (721, 1283), (241, 322), (3, 4), (1, 1)])
@pytest.mark.parametrize("k", [1, 2, 3, 4, 5])
def test_sample_is_the_strided_grid(h: int, w: int, k: int) -> None:
    img = np.random.default_rng(h * w + k).integers(0, 256, (h, w, 3), dtype=np.uint8)
    assert np.array_equal(_sample(img, k), img[::k, ::k])
    assert np.array_equal(_sample(img[:, :, 1].copy(), k), img[::k, ::k, 1])


def test_median_and_upper_mean_as_numpy() -> None:
    rng = np.random.default_rng(3)
    for n in range(1, 40):
        x = rng.integers(-300, 300, n).astype(np.int16)
        assert _median(x) == float(np.median(x))
        assert _upper_mean(x) == float(np.sort(x)[n // 2 :].mean())
