"""Pano-table unwarping against rendered truth (the acceptance figures of the pano-table).

A rendered SVP-mirror omni-image (eq. 2.1) with exact landmarks is calibrated
into a pano-mapping table; its views are compared with
- the *ceiling*: the same omni-image unwarped with the renderer's exact
  geometric mapping (eq. 2.1), sampled the same way (bilinear), and
- the *truth*: the view rendered directly from the scene, area-averaged.

PSNR is taken over pixels the camera sees whose source position lies at least
2 px inside the mirror disc (outside the cut-off circle and inside the rim):
at the disc's edges every unwarper blends in the dark surround.
"""

from __future__ import annotations

import numpy as np
import pytest

from omnidev.camera import Maps, build_maps, unwarp
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
from omnidev.views import CylinderPanorama, Panorama, Perspective, PlaneView, View
from tests.conftest import psnr

CAM = SvpHyperbolicCamera.default(640)
SCENE = RoomScene(0)
BAND = CAM.default_elevation_deg()

# Views no finer than the omni-image resolves: the 480-column panorama has no more
# columns than the omni-image's innermost ring (2 pi 77 px = 484 px); the others
# sample the scene at most about as finely as the omni-image does where they look.
RESOLVED: list[View] = [
    Panorama(480, 160, BAND),
    CylinderPanorama(480, 200, distance=2.0, z_bottom=-1.2, z_top=0.4),
    PlaneView(320, 240, distance=1.8, plane_width=2.4, z_bottom=-1.2, z_top=0.6),
    Perspective(320, 240, fov_deg=90, pan_deg=120, tilt_deg=-20),
]
FINER: list[View] = [Panorama(1024, 256, BAND), Panorama(2048, 512, BAND)]


@pytest.fixture(scope="module")
def omni() -> np.ndarray:
    return render_omni(CAM, SCENE, supersample=3)


@pytest.fixture(scope="module")
def table_calibration():
    lm = make_landmarks(CAM, SCENE, n=16, seed=0)
    uv = np.array([[m.u, m.v] for m in lm])
    xyz = np.array([[m.X, m.Y, m.Z] for m in lm])
    return calibrate(uv, xyz, np.array(SCENE.mirror_center_world), CAM.center, CAM.image_size)


def interior(maps: Maps, camera: SvpHyperbolicCamera, margin: float = 2.0) -> np.ndarray:
    """View pixels whose source lies ``margin`` px inside the mirror disc."""
    r = np.hypot(maps.map_x - camera.center[0], maps.map_y - camera.center[1])
    r_rim = camera.radius_of_elevation(np.array(camera.top_elevation))
    return maps.valid & (r >= camera.cutoff_radius + margin) & (r <= r_rim - margin)


def figures(omni, table, view):
    truth, seen = render_view(view, SCENE, camera=CAM)
    exact = build_maps(CAM, view)
    mask = seen & interior(exact, CAM)
    out = {"ceiling": psnr(unwarp(omni, exact), truth, mask)}
    for lookup in ("bilinear", "nearest"):
        maps = build_maps(PanoTableCamera(table, lookup), view)
        m = mask & maps.valid
        assert m.sum() > 0.5 * mask.sum()
        out[lookup] = psnr(unwarp(omni, maps), truth, m)
    return out


def test_radial_fit_residual(table_calibration):
    assert table_calibration.fit.rms_px < 0.5
    assert table_calibration.reprojection_px.max() < 0.5
    assert table_calibration.table.azimuth_sign == 1
    assert abs(table_calibration.table.azimuth_offset) < 1e-3


@pytest.mark.parametrize("view", RESOLVED, ids=lambda v: type(v).__name__)
def test_views_reach_the_ceiling_and_30_db(omni, table_calibration, view):
    f = figures(omni, table_calibration.table, view)
    print(
        f"{type(view).__name__} {view.width}x{view.height}: "
        + ", ".join(f"{k} {v:.2f} dB" for k, v in f.items())
    )
    assert f["bilinear"] >= f["ceiling"] - 1.0
    assert f["bilinear"] >= 30.0
    assert f["bilinear"] > f["nearest"]  # bilinear maps beat the nearest-entry lookup


@pytest.mark.parametrize("view", FINER, ids=lambda v: f"{v.width}x{v.height}")
def test_finer_views_still_follow_the_ceiling(omni, table_calibration, view):
    """Views finer than the omni-image: the ceiling itself drops; the table follows it."""
    f = figures(omni, table_calibration.table, view)
    print(
        f"Panorama {view.width}x{view.height}: "
        + ", ".join(f"{k} {v:.2f} dB" for k, v in f.items())
    )
    assert f["bilinear"] >= f["ceiling"] - 1.0
    assert f["bilinear"] > f["nearest"]


def test_pano_table_learns_a_fisheye_too():
    """The same table method on a dioptric camera (r linear in elevation: fits exactly)."""
    cam = EquidistantFisheyeCamera.default(480)
    lm = make_landmarks(cam, SCENE, n=12, seed=3)
    uv = np.array([[m.u, m.v] for m in lm])
    xyz = np.array([[m.X, m.Y, m.Z] for m in lm])
    cal = calibrate(uv, xyz, np.array(SCENE.mirror_center_world), cam.center, cam.image_size)
    assert cal.fit.rms_px < 1e-6
    omni = render_omni(cam, SCENE, supersample=2)
    view = PlaneView(
        240, 180, distance=1.8, plane_width=2.4, z_bottom=-1.0, z_top=0.8, azimuth_deg=90
    )
    truth, seen = render_view(view, SCENE, supersample=2, camera=cam)
    maps = build_maps(PanoTableCamera(cal.table), view)
    assert psnr(unwarp(omni, maps), truth, seen & maps.valid) >= 30.0
