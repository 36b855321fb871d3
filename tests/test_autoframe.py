"""Auto-framing (omnidev.autoframe, issue 16 deliverable 4) against rendered truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omnidev.autoframe import (
    AutoFrameConfig,
    AutoFramer,
    Follower,
    Target,
    count_reversals,
    seam_blobs,
    view_offset,
    wrap_deg,
)
from omnidev.evaluation.tasks.autoframe import run_video
from omnidev.sim.autoframe_video import draw_video
from omnidev.views import Panorama

PANO = Panorama(360, 90, (-45.0, 45.0))


def test_follower_is_rate_limited_and_goes_the_short_way() -> None:
    f = Follower(60.0, pan_deg=170.0, tilt_deg=0.0)
    poses = [f.step((-170.0, 0.0), 0.1) for _ in range(5)]
    # 20 degrees the short way (through 180) at 6 degrees a step: 176, -178, -172, -170
    assert [round(p, 6) for p, _ in poses] == [176.0, -178.0, -172.0, -170.0, -170.0]
    f = Follower(50.0)
    pan, tilt = f.step(Target(30.0, 40.0, 1, 100.0, True), 0.2)  # 50 deg away, 10 allowed
    assert math.hypot(pan, tilt) == pytest.approx(10.0)
    assert pan / tilt == pytest.approx(30.0 / 40.0)
    assert f.step(None, 1.0) == (pan, tilt)
    with pytest.raises(ValueError, match="max_deg_s"):
        Follower(0.0)


def test_a_blob_across_the_seam_is_one_blob_with_its_centroid_across_it() -> None:
    mask = np.zeros((20, 100), np.uint8)
    mask[5:15, 0:4] = 1  # 4 columns at the left edge
    mask[5:15, 96:100] = 1  # 4 at the right edge: one object
    mask[2:6, 50:56] = 1  # another
    blobs = sorted(seam_blobs(mask, 10, wrap=True))
    assert len(blobs) == 2
    x, y, area = blobs[0]
    assert (x, y, area) == pytest.approx((-0.5, 9.5, 80))
    assert len(seam_blobs(mask, 10, wrap=False)) == 3
    assert len(seam_blobs(mask, 30, wrap=True)) == 1  # the 24 px one is too small


def _frame(az_deg: float | None, rng: np.random.Generator) -> np.ndarray:
    """A textured 360x90 panorama (clockwise from azimuth 0) with a 12x40 px box at az."""
    yy, xx = np.mgrid[0:90, 0:360]
    img = 100 + 40 * np.sin(xx / 7.0) * np.cos(yy / 5.0)
    if az_deg is not None:
        col = (-az_deg) % 360.0 - 0.5  # column of the azimuth (clockwise, start 0)
        d = np.abs(((xx - col) + 180) % 360 - 180)
        img = np.where((d <= 6) & (yy >= 30) & (yy < 70), 220.0, img)
    img = img + rng.normal(0, 2, img.shape)
    return np.repeat(np.clip(img, 0, 255).astype(np.uint8)[..., None], 3, 2)


@pytest.mark.parametrize("method", ["mog2", "knn"])
def test_an_object_crossing_the_seam_stays_one_followed_track(method: str) -> None:
    framer = AutoFramer(AutoFrameConfig(PANO, method=method))
    rng = np.random.default_rng(3)
    for i in range(10):
        assert framer.update(_frame(None, rng), i / 10) is None  # no object yet
    tracks = set()
    errs = []
    for i in range(60):  # from azimuth 30 to -30 through the seam at 0, 1 degree a frame
        az = 30.0 - i
        t = framer.update(_frame(az, rng), (10 + i) / 10)
        if i >= 6:
            assert t is not None
            tracks.add(t.track)
            errs.append(abs(wrap_deg(t.pan_deg - az)))
            assert t.tilt_deg == pytest.approx(-5.0, abs=3.0)
    assert len(tracks) == 1
    assert max(errs) <= 4.0  # the dead zone (2 degrees) plus the filter's lag


def test_config_and_measures() -> None:
    with pytest.raises(ValueError, match="mog2, knn"):
        AutoFrameConfig(PANO, method="nope")
    with pytest.raises(ValueError, match="elevation_deg"):
        AutoFrameConfig(Panorama(360, 90))
    # 10 % of a 60-degree view's width: atan(0.2 tan 30 deg) = 6.59 degrees off-centre
    edge = math.degrees(math.atan(0.2 * math.tan(math.radians(30))))
    assert view_offset(20.0, 0.0, 60.0, 20.0 + edge, 0.0) == pytest.approx(0.1)
    assert view_offset(0.0, 0.0, 60.0, 180.0, 0.0) == math.inf
    assert count_reversals([0, 1, 2, 3, 2.5, 2.2, 3, 1.5, 0, 4], 1.0) == 2
    assert count_reversals([0, 0.4, 0, 0.4, 0], 1.0) == 0


def test_a_video_with_no_moving_object_gives_no_target() -> None:
    r = run_video(3, kind="empty", seconds=5.0, camera="fisheye")
    assert r["video"]["kind"] == "empty" and r["video"]["flicker"]
    assert r["targets"] == 0


# a sample of the tuning seeds (0-29): both camera kinds, a reversal, seam crossings
@pytest.mark.parametrize("seed", [1, 4, 6])
def test_rendered_videos_are_framed_within_the_bound(seed: int) -> None:
    r = run_video(seed)
    v = r["video"]
    assert v["kind"] == "normal"
    assert r["framed"] >= 0.95, r
    assert r["lock_on_s"] <= 1.0, r
    assert r["view_reversals"] <= r["object_reversals"], r
    assert r["false_target_frames"] == 0


def test_sample_covers_both_cameras_and_the_seam() -> None:
    vids = [draw_video(s).describe() for s in (1, 4, 6)]
    assert {v["camera"] for v in vids} == {"fisheye", "hyperbolic"}
    assert any(v["azimuth_range_deg"][0] < 0 < v["azimuth_range_deg"][1] for v in vids)


def test_the_first_step_after_lock_on_does_not_turn_the_view_back() -> None:
    """Seed 5027 (fisheye, 480 px, 10 fps; a held-out seed of the first evaluation): the
    person appears standing; the view's acquiring swing stopped at the first, partial
    blob's centroid, and a tilt step then dragged the pan 2.5 degrees the other way,
    turning the view back where the person did not turn. Pan and tilt now leave their
    zones each on its own, and the first pan step after lock-on needs the reverse zone."""
    r = run_video(5027)
    assert r["video"]["kind"] == "normal"
    assert r["view_reversals"] <= r["object_reversals"], r
    assert r["framed"] >= 0.95, r
