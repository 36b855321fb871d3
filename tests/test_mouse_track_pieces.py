"""The fast scoring of the tracking template (kernel cut into pieces) against the
straightforward one (one cv2.filter2D with the whole kernel): same taps, same centers."""

from __future__ import annotations

import numpy as np
import pytest

from omnidev.mouse.detect import to_gray
from omnidev.mouse.track import _DIRECT_AREA, template_kernel, template_pieces, track_circle
from omnidev.sim import monitor as mon
from omnidev.sim.handcam import HandCamera


@pytest.mark.parametrize(
    "r,n",
    [  # every radius the tracker uses with each bar length (r >= n/2 + 1)
        (r, n)
        for n in (2, 4, 6, 8)
        for r in (2, 3, 4, 5, 6, 7, 9, 12, 16, 23, 31)
        if r >= n // 2 + 1
    ],
)
def test_pieces_hold_exactly_the_kernels_taps(r: int, n: int) -> None:
    k = template_kernel(r, n)
    c = k.shape[0] // 2
    rebuilt = np.zeros_like(k)
    pieces = template_pieces(r, n)
    assert 1 <= len(pieces) <= 8
    for p in pieces:
        ph, pw = p.kernel.shape
        assert ph * pw <= _DIRECT_AREA  # small enough for filter2D's direct path
        rebuilt[c + p.dy : c + p.dy + ph, c + p.dx : c + p.dx + pw] += p.kernel
    assert np.array_equal(rebuilt, k)


def rendered(trajectory: str, index: int) -> tuple[np.ndarray, list[tuple[float, float] | None]]:
    img, truth = mon.render_frame(
        HandCamera.default(),
        mon.MonitorScene(0),
        trajectory,
        index,
        supersample=2,
        blur_samples=2,
    )
    return to_gray(img), truth.landmarks_uv


# starting points around each landmark (in radii), radii tried (px), and points
# whose windows the picture's border cuts
SHIFTS = [(0.0, 0.0), (0.4, -0.3), (1.7, -1.3), (-3.0, 2.2)]
RADII = [4.6, 6.56, 9.3]
BORDER = [(2.0, 3.0), (637.0, 240.5), (320.0, 478.2), (12.4, 470.0), (630.0, 6.0)]


@pytest.mark.parametrize(
    "trajectory,index",
    [("drift", 0), ("drift", 17), ("sweep", 9), ("roll", 20), ("oblique", 25), ("partial", 40)],
)
def test_pieces_and_whole_kernel_give_the_same_centers(trajectory: str, index: int) -> None:
    gray, uv = rendered(trajectory, index)
    starts = [
        (u + sx * r, v + sy * r, r)
        for p in uv
        if p is not None
        for u, v in [p]
        for sx, sy in SHIFTS
        for r in RADII
    ] + [(x, y, r) for x, y in BORDER for r in RADII]
    found = 0
    for x, y, r in starts:
        fast = track_circle(gray, x, y, r, radius_steps=2)
        ref = track_circle(gray, x, y, r, radius_steps=2, correlate="kernel")
        assert (fast is None) == (ref is None), (x, y, r, fast, ref)
        if fast is None or ref is None:
            continue
        found += 1
        assert abs(fast.x - ref.x) <= 1e-3 and abs(fast.y - ref.y) <= 1e-3, (x, y, r, fast, ref)
        assert fast.r == ref.r and abs(fast.contrast - ref.contrast) <= 1e-3, (fast, ref)
    assert found >= len(RADII) * len([p for p in uv if p is not None])  # not vacuous


def test_unknown_correlation_is_refused() -> None:
    gray = np.full((100, 100), 128, np.uint8)
    with pytest.raises(ValueError, match="correlate"):
        track_circle(gray, 50.0, 50.0, 6.0, correlate="fft")  # type: ignore[arg-type]
