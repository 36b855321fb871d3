"""omnidev.ptz: the view controller's rate limit, wrap-around and limits; move parsing."""

from __future__ import annotations

import math

import pytest

from omnidev.errors import OmnidevError
from omnidev.ptz import Pose, ViewController, parse_moves


def test_step_is_rate_limited_along_a_straight_line():
    c = ViewController(Pose(0.0, 0.0, 90.0), max_deg_s=50.0)
    c.set_target(pan=30.0, tilt=40.0)  # 50 degrees away: one second
    p = c.step(0.1)
    assert math.hypot(p.pan, p.tilt) == pytest.approx(5.0)
    assert p.pan / p.tilt == pytest.approx(30 / 40)  # both axes arrive together
    assert p.fov == 90.0 and not c.settled
    for _ in range(8):
        c.step(0.1)
    assert not c.settled
    assert c.step(0.1) == Pose(30.0, 40.0, 90.0) and c.settled


def test_pan_goes_the_short_way_round():
    c = ViewController(Pose(170.0, 0.0, 60.0), max_deg_s=10.0)
    c.set_target(pan=-170.0)
    p = c.step(1.0)
    assert p.pan == pytest.approx(-180.0)  # 170 -> 180 (= -180), not back through 0
    assert c.step(1.0).pan == pytest.approx(-170.0)


def test_zero_rate_jumps_and_limits_clamp():
    c = ViewController(Pose(0.0, 0.0, 60.0), max_deg_s=0.0)
    c.move(tilt=200.0, fov=500.0)
    assert c.target == Pose(0.0, 90.0, 179.0)
    assert c.step(0.0) == c.target
    c.move(fov=-1000.0)
    assert c.step(0.0).fov == 1.0
    with pytest.raises(ValueError, match="max_deg_s"):
        ViewController(Pose(0, 0, 60), max_deg_s=-1)


def test_parse_moves():
    assert parse_moves(["pan=30", "tilt=+5", "fov=-10"]) == (
        {"pan": 30.0},
        {"tilt": 5.0, "fov": -10.0},
    )
    assert parse_moves(["pan==-30"]) == ({"pan": -30.0}, {})
    for bad, msg in (
        (["zoom=2"], "unknown axis"),
        (["pan"], "AXIS=VALUE"),
        (["pan=x"], "not a number"),
        (["pan=nan"], "finite"),
        (["pan=1", "pan=+2"], "twice"),
        ([], "at least one"),
    ):
        with pytest.raises(OmnidevError, match=msg):
            parse_moves(bad)


def test_coarse_maps_are_within_a_hundredth_of_a_pixel_of_exact_ones(tmp_path):
    """Rays at every 4th pixel, bilinear in between: a 190-degree fisheye, a 640x480 view."""
    import numpy as np

    import omnidev
    from omnidev.camera import build_maps
    from omnidev.ptz import coarse_maps
    from omnidev.views import Perspective
    from tests.test_cli_unwarp_video import fisheye_clip

    _, cam = fisheye_clip(tmp_path, frames=1)
    camera = omnidev.load_camera(cam)
    for view in (Perspective(640, 480, 70.0, 30.0, 40.0), Perspective(640, 480, 100.0, 0.0, 0.0)):
        exact, coarse = build_maps(camera, view), coarse_maps(camera, view, 4)
        both = exact.valid & coarse.valid
        assert both.sum() > 0.3 * both.size
        err = np.hypot(exact.map_x - coarse.map_x, exact.map_y - coarse.map_y)[both]
        assert err.max() < 0.01, err.max()
        lost = (exact.valid & ~coarse.valid).sum()  # only along the edge of the camera's view
        assert lost < 4 * 4 * (640 + 480), lost
        assert not (coarse.valid & ~exact.valid).any()
    one = coarse_maps(camera, Perspective(64, 48, 60.0), 1)
    assert np.array_equal(one.map_x, build_maps(camera, Perspective(64, 48, 60.0)).map_x)
