"""The renderer's geometry is exact: eq. 2.1 and its inverse, landmarks, determinism."""

from __future__ import annotations

import math

import numpy as np

from omnidev.panotable.center import detect_omni_circles
from omnidev.sim import (
    EquidistantFisheyeCamera,
    RoomScene,
    SvpHyperbolicCamera,
    make_landmarks,
    render_omni,
)

CAM = SvpHyperbolicCamera.default(640)


def test_back_projection_inverts_eq_2_1_over_the_disc():
    v, u = np.mgrid[0:640:0.7, 0:640:0.7]
    uv = np.stack([u, v], -1).reshape(-1, 2)
    r = np.hypot(uv[:, 0] - CAM.center[0], uv[:, 1] - CAM.center[1])
    disc = (r > CAM.cutoff_radius) & (r < 0.48 * 640)
    d = CAM.back_project(uv[disc])
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    uv2, ok = CAM.project(d * 3.7)
    assert ok.all()
    assert np.max(np.abs(uv2 - uv[disc])) < 1e-9


def test_eq_2_1_by_hand():
    _a, b, c, f = CAM.a, CAM.b, CAM.c, CAM.f
    for p in ([2.0, 1.0, -0.5], [-1.0, 2.5, 0.3], [0.4, -1.1, -1.2]):
        x, y, z = p
        den = (b * b + c * c) * z - 2 * b * c * math.sqrt(x * x + y * y + z * z)
        expect = [
            CAM.center[0] + f * (b * b - c * c) * x / den,
            CAM.center[1] + f * (b * b - c * c) * y / den,
        ]
        uv, _ = CAM.project(np.array(p))
        np.testing.assert_allclose(uv, expect, rtol=1e-12)


def test_radius_is_monotonic_and_band_is_the_mirror():
    rho = np.radians(np.linspace(-80, 12, 500))
    r = CAM.radius_of_elevation(rho)
    assert np.all(np.diff(r) > 0)
    lo, hi = CAM.default_elevation_deg()
    assert abs(hi - 12.62) < 0.01  # rim of a 50 mm mirror with a = 28.1, b = 23.4
    assert abs(CAM.radius_of_elevation(np.radians(hi)) - 0.48 * 640) < 1e-6
    assert abs(CAM.radius_of_elevation(np.radians(lo)) - CAM.cutoff_radius) < 1e-6
    # points above the rim's elevation are not seen
    _, ok = CAM.project(np.array([[2.0, 0.0, 2.0 * math.tan(math.radians(hi + 0.5))]]))
    assert not ok.any()


def test_fisheye_round_trip():
    cam = EquidistantFisheyeCamera.default(480)
    rng = np.random.default_rng(0)
    ang = rng.uniform(0, cam.max_angle, 1000)
    az = rng.uniform(-math.pi, math.pi, 1000)
    d = np.stack([np.sin(ang) * np.cos(az), np.sin(ang) * np.sin(az), np.cos(ang)], 1)
    uv, _ = cam.project(d)
    np.testing.assert_allclose(cam.back_project(uv), d, atol=1e-12)


def test_landmarks_are_exact_and_span_the_band():
    scene = RoomScene(0)
    lm = make_landmarks(CAM, scene, n=16, seed=0)
    world = np.array([[m.X, m.Y, m.Z] for m in lm])
    uv = np.array([[m.u, m.v] for m in lm])
    p = world - np.array(scene.mirror_center_world)
    uv2, ok = CAM.project(p)
    assert ok.all() and np.max(np.abs(uv2 - uv)) < 1e-9
    # each landmark lies on a surface of the room
    dist, _ = scene.intersect(np.zeros_like(p), p / np.linalg.norm(p, axis=1, keepdims=True))
    np.testing.assert_allclose(dist, np.linalg.norm(p, axis=1), rtol=1e-12)
    rho = np.degrees(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1])))
    lo, hi = CAM.default_elevation_deg()
    assert rho.min() < lo + 1.5 and rho.max() > hi - 1.5
    theta = np.arctan2(p[:, 1], p[:, 0])
    assert np.ptp(np.sort(theta)) > 5.0  # all around


def test_render_is_deterministic_and_shows_disc_and_cutoff():
    small = SvpHyperbolicCamera.default(200)
    a = render_omni(small, RoomScene(3), supersample=2, noise_sigma=2.0, seed=5)
    b = render_omni(small, RoomScene(3), supersample=2, noise_sigma=2.0, seed=5)
    c = render_omni(small, RoomScene(4), supersample=2, noise_sigma=2.0, seed=5)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    circles = detect_omni_circles(render_omni(CAM, RoomScene(0), supersample=2))
    assert np.hypot(circles.center[0] - CAM.center[0], circles.center[1] - CAM.center[1]) < 0.3
    assert abs(circles.cutoff_radius - CAM.cutoff_radius) < 1.0
    assert abs(circles.disc_radius - 0.48 * 640) < 1.5
