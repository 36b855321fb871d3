"""Plane: a perspective view of any plane (centre, normal, size), for every camera kind.

Geometry against the view's definition (every output point on the plane, upright axes, the
vertical and horizontal special cases equal PlaneView and TopView), the fisheye fast path
against the reference path, and unwarped views against truth renders: a fisheye and an SVP
mirror camera with the pano-table (omnidev.sim's room, truth rendered from the scene along
the view's rays), and a misaligned non-SVP mirror camera (omnidev.sim.nonsvp's ray tracer:
every plane point coloured along the ray from its own mirror point).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from omnidev.camera import build_maps, project_maps, unwarp
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.models import KannalaBrandt, Scaramuzza, Unified
from omnidev.views import Plane, PlaneView, TopView, plane_axes
from omnidev.viewspec import ViewSpecError, parse_view
from tests.conftest import psnr


def random_planes(seed: int, n: int) -> list[Plane]:
    """Planes at 1-4 m, normals anywhere (tilts up to 80 degrees from facing the viewpoint)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        dist = rng.uniform(1.0, 4.0)
        axis = rng.normal(size=3)
        axis -= (axis @ d) * d
        axis /= np.linalg.norm(axis)
        tilt = math.radians(rng.uniform(0, 80))
        normal = math.cos(tilt) * d + math.sin(tilt) * axis
        size = rng.uniform(0.3, 1.2) * dist
        out.append(
            Plane(
                int(rng.integers(40, 90)),
                int(rng.integers(30, 70)),
                tuple(dist * d),
                tuple(normal * rng.choice([-1.0, 1.0])),
                size,
                size * rng.uniform(0.5, 1.5),
                float(rng.uniform(-30, 30)),
            )
        )
    return out


@pytest.mark.parametrize("plane", random_planes(1, 12), ids=lambda p: f"{p.width}x{p.height}")
def test_points_lie_on_the_plane_in_an_upright_rectangle(plane: Plane) -> None:
    pts = plane.points()
    c = np.asarray(plane.center)
    n = np.asarray(plane.normal) / np.linalg.norm(plane.normal)
    ax = plane.axes()
    assert np.allclose(ax.T @ ax, np.eye(3), atol=1e-12)
    assert np.linalg.det(ax) == pytest.approx(1.0)  # right, down, forward: right-handed
    assert abs(abs(ax[:, 2] @ n) - 1) < 1e-12 and ax[:, 2] @ c > 0  # looking away from O
    assert np.abs((pts - c) @ n).max() < 1e-9 * np.abs(c).max()
    local = (pts - c) @ ax[:, :2]
    half = np.array([plane.plane_width, plane.plane_height]) / 2
    assert np.all(np.abs(local) < half)
    # cell centres: first and last are half a cell inside the edges
    cell = 2 * half / [plane.width, plane.height]
    assert local[0, 0] == pytest.approx(-half + cell / 2)
    assert local[-1, -1] == pytest.approx(half - cell / 2)
    # upright before the roll: down has no component against the world's -z
    unrolled = plane_axes(plane.center, plane.normal, 0.0)
    assert unrolled[2, 0] == pytest.approx(0.0, abs=1e-12)  # right is horizontal
    assert unrolled[2, 1] <= 1e-12  # down points down (or is horizontal)


def test_vertical_plane_is_plane_view_and_horizontal_plane_is_top_view() -> None:
    az = math.radians(130.0)
    old = PlaneView(
        64, 48, distance=2.5, plane_width=3.0, z_bottom=-1.5, z_top=0.5, azimuth_deg=130
    )
    new = Plane(
        64,
        48,
        (2.5 * math.cos(az), 2.5 * math.sin(az), -0.5),
        (math.cos(az), math.sin(az), 0),
        3.0,
        2.0,
    )
    assert np.abs(old.points() - new.points()).max() < 1e-12
    top = TopView(50, 40, extent_x=4.0, extent_y=3.0, z=-2.0, center_x=0.5, center_y=-0.3)
    floor = Plane(50, 40, (0.5, -0.3, -2.0), (0, 0, 1), 4.0, 3.0)
    assert np.abs(top.points() - floor.points()).max() < 1e-12
    # a ceiling seen from below: +y up, +x on the left (the sky as a viewer lying down sees it)
    ax = Plane(10, 10, (0, 0, 3.0), (0, 0, -1), 1.0, 1.0).axes()
    assert np.allclose(ax[:, 0], [-1, 0, 0]) and np.allclose(ax[:, 1], [0, -1, 0])
    # roll +90: the image turns clockwise, so right becomes the old up
    rolled = Plane(10, 10, (2.0, 0, 0), (1, 0, 0), 1.0, 1.0, roll_deg=90).axes()
    assert np.allclose(rolled[:, 0], [0, 0, 1], atol=1e-12)


def test_bad_planes_are_refused() -> None:
    with pytest.raises(ValueError, match="passes through the viewpoint"):
        Plane(10, 10, (1.0, 0, 0), (0, 1, 0), 1.0, 1.0)
    with pytest.raises(ValueError, match="normal must not be zero"):
        Plane(10, 10, (1.0, 0, 0), (0, 0, 0), 1.0, 1.0)
    with pytest.raises(ValueError, match="plane_width > 0"):
        Plane(10, 10, (1.0, 0, 0), (1, 0, 0), 0.0, 1.0)


def test_view_spec() -> None:
    v = parse_view("plane:320x240,c=2000:-500:-1000,n=1:0:1,w=1500,h=1000,roll=5")
    assert isinstance(v, Plane)
    assert v.center == (2000.0, -500.0, -1000.0) and v.normal == (1.0, 0.0, 1.0)
    assert (v.plane_width, v.plane_height, v.roll_deg) == (1500.0, 1000.0, 5.0)
    assert isinstance(parse_view("plane:64x48,d=2,w=3,z=-1:1"), PlaneView)
    for spec, msg in [
        ("plane:64x48,c=1:2,n=1:0:0,w=1,h=1", "c must be X:Y:Z"),
        ("plane:64x48,c=1:0:0,n=1:0:0,w=1", "needs h"),
        ("plane:64x48,c=1:0:0,n=1:0:0,w=1,h=1,d=2", "does not go with c and n"),
        ("plane:64x48,c=1:0:0,n=0:1:0,w=1,h=1", "passes through the viewpoint"),
    ]:
        with pytest.raises(ViewSpecError, match=msg):
            parse_view(spec)


LENSES = {
    "kb4": (KannalaBrandt(290.0, 289.3, 402.1, 397.6, (0.012, -0.006, 0.0021, -0.0004)), "up"),
    "mei": (Unified(455.0, 454.1, 398.9, 402.4, 0.95, k1=-0.03, k2=0.006), "mirror-up"),
    "scaramuzza": (
        Scaramuzza((-225.0, 0.0, 6.3e-4, -1.1e-7, 2.4e-10), 401.0, 399.5, 1.0004, 2e-4, 2e-4),
        "up",
    ),
}


@pytest.mark.parametrize("name", sorted(LENSES))
def test_fisheye_fast_maps_equal_the_reference_path(name: str) -> None:
    lens, mount = LENSES[name]
    if isinstance(lens, Scaramuzza):  # the fast path needs OCamCalib's world2cam polynomial
        from omnidev.fisheye.ocamcalib import fit_invpol

        lens = fit_invpol(lens, (800, 800))
    cam = FisheyeCamera(lens, (800, 800), MOUNTS[mount])
    worst = 0.0
    seen = 0
    for plane in random_planes(2, 16):
        fast = build_maps(cam, plane)
        ref = project_maps(cam, plane)
        assert np.array_equal(fast.valid, ref.valid)
        if ref.valid.any():
            d = np.hypot(fast.map_x - ref.map_x, fast.map_y - ref.map_y)[ref.valid]
            worst = max(worst, float(d.max()))
            seen += int(ref.valid.sum())
    print(f"{name}: fast vs reference maps over {seen} plane pixels: max {worst:.2e} px")
    assert seen > 5000 and worst < 1e-3


def test_fisheye_and_pano_table_plane_views_against_truth() -> None:
    from omnidev.panotable.camfile import PanoTableCamera
    from omnidev.panotable.table import calibrate
    from omnidev.sim import (
        EquidistantFisheyeCamera,
        RoomScene,
        SvpHyperbolicCamera,
        make_landmarks,
        render_omni,
        render_view,
    )

    scene = RoomScene(0)
    below = [  # what the mirror sees (-53 to 13 degrees): a slanted wall, a tilted floor patch
        Plane(200, 150, (0.3, 1.6, -0.9), (0.2, 1.0, 0.6), 2.0, 1.5, 8.0),
        Plane(200, 150, (1.2, -0.4, -1.1), (0.3, -0.1, 1.0), 2.2, 1.6),
    ]
    above = [  # what the upward fisheye sees (-5 to 90 degrees): a leaning wall, the ceiling
        Plane(200, 150, (1.5, -0.5, 0.6), (1.0, -0.3, -0.4), 1.6, 1.2, -6.0),
        Plane(200, 150, (0.5, 1.0, 1.4), (0.2, 0.7, 1.0), 1.8, 1.4),
    ]
    for cam, tilted in (
        (EquidistantFisheyeCamera.default(480), above),
        (SvpHyperbolicCamera.default(640), below),
    ):
        omni = render_omni(cam, scene, supersample=2)
        lm = make_landmarks(cam, scene, n=16, seed=0)
        table = calibrate(
            np.array([[m.u, m.v] for m in lm]),
            np.array([[m.X, m.Y, m.Z] for m in lm]),
            np.array(scene.mirror_center_world),
            cam.center,
            cam.image_size,
        ).table
        for plane in tilted:
            truth, seen = render_view(plane, scene, supersample=2, camera=cam)
            exact = build_maps(cam, plane)
            table_maps = build_maps(PanoTableCamera(table), plane)
            m = seen & exact.valid & table_maps.valid
            assert m.mean() > 0.5
            ceiling = psnr(unwarp(omni, exact), truth, m)
            got = psnr(unwarp(omni, table_maps), truth, m)
            print(f"{type(cam).__name__}: plane view ceiling {ceiling:.2f} dB, table {got:.2f} dB")
            assert ceiling >= 30.0 and got >= ceiling - 1.0


def test_nonsvp_plane_view_against_the_ray_tracer() -> None:
    from omnidev.nonsvp.camfile import NonSvpCameraModel
    from omnidev.nonsvp.unwarp import backprojected_view, dense_maps
    from omnidev.sim import nonsvp as sim_nonsvp
    from omnidev.sim.pseudo_target import make_scene

    cam = sim_nonsvp.preset_camera("large", (640, 480))
    scene = make_scene("textured", 0)
    omni, _ = sim_nonsvp.render_omni(cam, scene, supersample=1)
    # a tilted patch of ground and a leaning wall, in mm
    planes = [
        Plane(160, 120, (900.0, 600.0, -1800.0), (0.4, 0.2, 1.0), 1800.0, 1300.0),
        Plane(160, 120, (-1300.0, -200.0, -900.0), (-1.0, -0.1, -0.5), 1600.0, 1200.0, -10.0),
    ]
    for plane in planes:
        truth, seen = sim_nonsvp.render_view_plane(cam, scene, plane, supersample=2)
        mx, my, ok = dense_maps(cam, plane)
        cx, cy, cok = sim_nonsvp.view_plane_map(cam, plane)
        m = seen & ok & cok
        assert m.mean() > 0.5
        gap = float(np.hypot(mx - cx, my - cy)[m].max())
        dense = cv2.remap(omni, mx, my, cv2.INTER_LINEAR)
        ceiling = cv2.remap(omni, cx, cy, cv2.INTER_LINEAR)
        p_dense, p_ceil = psnr(dense, truth, m), psnr(ceiling, truth, m)
        # the camera-model path (omnidev unwarp) and the back-projection land on the plane too
        maps = build_maps(NonSvpCameraModel(cam), plane)
        p_model = psnr(unwarp(omni, maps), truth, m & maps.valid)
        raw, filled = backprojected_view(cam, omni, plane)
        p_back = psnr(raw, truth, m & filled)
        print(
            f"non-SVP plane: dense {p_dense:.2f} dB, ceiling {p_ceil:.2f} dB, camera model "
            f"{p_model:.2f} dB, back-projected (filled {filled[m].mean():.2f}) {p_back:.2f} dB; "
            f"dense vs exact map max {gap:.1e} px"
        )
        assert gap < 1e-3
        assert p_dense >= p_ceil - 0.5 and p_model >= p_ceil - 0.5
        assert p_back >= p_ceil - 6.0 and filled[m].mean() > 0.05
