"""Fisheye maps (omnidev.fisheye.maps) against the reference path and against OpenCV (issue 7).

- The fast path (separable rays, float32) equals the plain float64 path
  (view points -> FisheyeCamera.project) for every model with a fast formula and
  every view type.
- Perspective maps agree with cv2.fisheye.initUndistortRectifyMap (KB4) and
  cv2.omnidir.initUndistortRectifyMap (Mei, RECTIFY_PERSPECTIVE) within 0.05 px
  wherever both are valid, with R = (mount @ view rotation)^T and P the view's
  pinhole matrix (omnidev.fisheye.maps.rotation_for_opencv / camera_matrix_for_opencv).
- Beyond 180 degrees: what OpenCV 5.0 measurably does wrong, and that omnidev's
  maps stay finite and masked exactly by the lens's field of view.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest

from omnidev.camera import INVALID, build_maps, project_maps
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.maps import (
    camera_matrix_for_opencv,
    reference_maps,
    rotation_for_opencv,
    view_maps,
)
from omnidev.fisheye.models import (
    EUCM,
    DoubleSphere,
    FieldOfView,
    IdealFisheye,
    KannalaBrandt,
    Scaramuzza,
    Unified,
)
from omnidev.views import (
    CylinderPanorama,
    Equirectangular,
    Panorama,
    Perspective,
    PlaneView,
    TopView,
)

# TUM-VI cam0 (tumvi_512_kb4_official.yaml) and the Mei paracatadioptric camera of
# shared/realdata (xmba15/omnidirectional_camera's cv::omnidir result), typed in here
# so that these tests run without the real data.
TUMVI_KB4 = KannalaBrandt(
    190.97847715128717,
    190.9733070521226,
    254.93170605935475,
    256.8974428996504,
    (0.0034823894022493434, 0.0007150348452162257, -0.0020532361418706202, 0.00020293673591811182),
)
MEI_PARA = Unified(
    366.0786746575819,
    366.1677891988819,
    643.7193980161953,
    521.3166467512945,
    1.44309762366835,
    skew=-1.730277473341805,
    k1=0.1097909284122646,
    k2=0.216601395090228,
    p1=0.0008254647531474698,
    p2=-0.0002583633785147333,
)
# A 200-degree KB4 lens (100 degrees from the axis fit in the 1024 px image).
KB4_200 = KannalaBrandt(290.0, 290.0, 511.5, 511.5, (-0.01, 0.001, 0.0, 0.0))

LENSES = {
    "kb4": (TUMVI_KB4, (512, 512)),
    "mei": (MEI_PARA, (1280, 1024)),
    "equisolid": (IdealFisheye("equisolid", 300.0, 639.5, 479.5, aspect=1.01), (1280, 960)),
    "ds": (DoubleSphere(158.28, 158.26, 254.96, 256.90, -0.1756, 0.5932), (512, 512)),
    "eucm": (EUCM(157.8, 157.7, 254.9, 256.9, 0.5, 1.2), (512, 512)),
    # TUM monoVO's FOV calibration (camera-intrinsic-model-rs): rays up to 90 degrees on the image
    "fov": (FieldOfView(446.91584, 447.071232, 631.2192, 510.997504, 0.933271), (1280, 1024)),
    "scaramuzza": (  # matsuren's calib_results_0.txt (shared/realdata, MIT)
        Scaramuzza(
            (-471.4441, 0.0, 7.356108e-04, -3.773045e-07, 5.800006e-10),
            794.308657,
            798.175741,
            1.000305,
            -0.000277,
            -0.000925,
            (
                772.405470,
                504.754051,
                7.034666,
                45.327180,
                54.651570,
                0.458049,
                -7.873745,
                15.588713,
                13.743404,
                2.968883,
            ),
        ),
        (1600, 1600),
    ),
}

VIEWS = [
    Perspective(160, 120, 100.0, pan_deg=30.0, tilt_deg=40.0, roll_deg=10.0),
    Equirectangular(180, 90, tilt_deg=60.0),
    Panorama(180, 45),
    CylinderPanorama(160, 40, 1.0, -1.0, 1.0),
    PlaneView(120, 80, 2.0, 3.0, -1.0, 1.0, 45.0),
    TopView(100, 100, 4.0, 4.0, 1.0),
]


def _angle_from_axis_deg(camera: FisheyeCamera, rays: np.ndarray) -> np.ndarray:
    opt = rays @ camera.mount.T
    return np.degrees(np.arctan2(np.hypot(opt[..., 0], opt[..., 1]), opt[..., 2]))


def _inside(mx: np.ndarray, my: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    w, h = size
    return (mx >= -0.5) & (mx <= w - 0.5) & (my >= -0.5) & (my <= h - 0.5)


# ---------------------------------------------------------------- fast path = reference


@pytest.mark.parametrize("name", sorted(LENSES))
@pytest.mark.parametrize("mount", ["up", "forward", "down"])
def test_fast_maps_equal_the_reference_path(name, mount):
    lens, size = LENSES[name]
    camera = FisheyeCamera(lens, size, MOUNTS[mount])
    compared = 0
    for view in VIEWS:
        fast, ref = view_maps(camera, view), reference_maps(camera, view)
        assert fast.source_size == ref.source_size and fast.shape == ref.shape
        both = fast.valid & ref.valid
        compared += int(both.sum())
        err = np.hypot(fast.map_x - ref.map_x, fast.map_y - ref.map_y)[both]
        assert err.max(initial=0.0) < 1e-3, (name, mount, view)
        # masks differ at most on a few rays within float32 rounding of a limit
        differ = fast.valid != ref.valid
        assert differ.sum() <= 2, (name, mount, view, int(differ.sum()))
        assert np.all(fast.map_x[~fast.valid] == INVALID)
        assert np.all(fast.map_y[~fast.valid] == INVALID)
        assert fast.map_x.dtype == np.float32 and fast.valid.dtype == np.bool_
    assert compared > 10000  # of 77200 view pixels


def test_build_maps_takes_the_cameras_fast_route_when_it_has_one():
    camera = FisheyeCamera(TUMVI_KB4, (512, 512), MOUNTS["forward"])
    view = Perspective(64, 48, 90.0, pan_deg=20.0)
    maps = build_maps(camera, view)
    fast = view_maps(camera, view)
    assert np.array_equal(maps.map_x, fast.map_x) and np.array_equal(maps.valid, fast.valid)
    plain = project_maps(camera, view)
    assert np.abs(maps.map_x - plain.map_x).max() < 1e-3 and np.array_equal(maps.valid, plain.valid)


def test_max_angle_deg_limits_the_fast_maps_as_the_reference():
    camera = FisheyeCamera(TUMVI_KB4, (512, 512), MOUNTS["up"], max_angle_deg=70.0)
    view = Equirectangular(360, 180)
    fast, ref = view_maps(camera, view), reference_maps(camera, view)
    assert (fast.valid != ref.valid).sum() <= 2
    ang = _angle_from_axis_deg(camera, view.points())
    assert np.all(ang[fast.valid] <= 70.0 + 1e-4)
    assert np.all(fast.valid[ang < 69.9])  # the whole 70-degree disc lies on the image


def test_fov_fast_maps_stop_at_90_degrees_and_at_max_angle_deg():
    # TUM monoVO's lens centred in a 1600 px square: the 90-degree circle (752 px) fits
    lens, size = dataclasses.replace(LENSES["fov"][0], cx=799.5, cy=799.5), (1600, 1600)
    view = Equirectangular(360, 180)
    for limit in (None, 60.0):
        camera = FisheyeCamera(lens, size, MOUNTS["up"], max_angle_deg=limit)
        fast, ref = view_maps(camera, view), reference_maps(camera, view)
        assert (fast.valid != ref.valid).sum() <= 2
        ang = _angle_from_axis_deg(camera, view.points())
        top = 90.0 if limit is None else limit
        assert np.all(ang[fast.valid] < top + 1e-4) and fast.valid[ang < top - 0.1].all()


# ---------------------------------------------------------------- against OpenCV


def _cv_fisheye_maps(camera: FisheyeCamera, view: Perspective) -> tuple[np.ndarray, np.ndarray]:
    """cv2.fisheye.initUndistortRectifyMap for the same lens, view and mount."""
    lens = camera.lens
    assert isinstance(lens, KannalaBrandt)
    K = np.array([[lens.fx, lens.skew, lens.cx], [0, lens.fy, lens.cy], [0, 0, 1.0]])
    R = rotation_for_opencv(view, camera.mount)
    P = camera_matrix_for_opencv(view)
    mx, my = cv2.fisheye.initUndistortRectifyMap(
        K, np.array(lens.k), R, P, (view.width, view.height), cv2.CV_32FC1
    )
    return mx, my


def _cv_omnidir_maps(camera: FisheyeCamera, view: Perspective) -> tuple[np.ndarray, np.ndarray]:
    """cv2.omnidir.initUndistortRectifyMap (RECTIFY_PERSPECTIVE) for the same lens, view, mount."""
    lens = camera.lens
    assert isinstance(lens, Unified)
    K = np.array([[lens.fx, lens.skew, lens.cx], [0, lens.fy, lens.cy], [0, 0, 1.0]])
    D = np.array([[lens.k1, lens.k2, lens.p1, lens.p2]])
    R = rotation_for_opencv(view, camera.mount)
    P = camera_matrix_for_opencv(view)
    mx, my = cv2.omnidir.initUndistortRectifyMap(
        K,
        D,
        np.array([[lens.xi]]),
        R,
        P,
        (view.width, view.height),
        cv2.CV_32FC1,
        cv2.omnidir.RECTIFY_PERSPECTIVE,
    )
    return mx, my


# (mount, pan, tilt, roll, fov): off-axis, rolled, wide and narrow views
SETTINGS = [
    ("forward", 0.0, 0.0, 0.0, 90.0),
    ("forward", 30.0, 20.0, 0.0, 70.0),
    ("forward", -60.0, -10.0, 15.0, 100.0),
    ("forward", 0.0, 89.0, 0.0, 120.0),
    ("up", 0.0, 45.0, 0.0, 90.0),
    ("up", 150.0, 90.0, -30.0, 60.0),
    ("up", -60.0, 35.0, 15.0, 100.0),
    ("down", 30.0, -25.0, 0.0, 70.0),
    ("down", 90.0, -105.0, 5.0, 150.0),
]


@pytest.mark.parametrize(("mount", "pan", "tilt", "roll", "fov"), SETTINGS)
def test_perspective_maps_agree_with_cv2_fisheye(mount, pan, tilt, roll, fov):
    camera = FisheyeCamera(TUMVI_KB4, (512, 512), MOUNTS[mount])
    view = Perspective(320, 240, fov, pan, tilt, roll)
    ours = view_maps(camera, view)
    mx, my = _cv_fisheye_maps(camera, view)
    cv_valid = _inside(mx, my, camera.image_size)
    both = ours.valid & cv_valid
    assert both.sum() > 0.3 * both.size
    err = np.hypot(ours.map_x - mx, ours.map_y - my)[both]
    assert err.max() < 0.05, err.max()
    # OpenCV never sees a pixel omnidev masks (it only loses rays beyond 90 degrees,
    # see test_kb4_beyond_90_degrees_opencv_drops_what_the_lens_sees)
    assert not np.any(cv_valid & ~ours.valid)


@pytest.mark.parametrize(("mount", "pan", "tilt", "roll", "fov"), SETTINGS)
def test_perspective_maps_agree_with_cv2_omnidir(mount, pan, tilt, roll, fov):
    camera = FisheyeCamera(MEI_PARA, (1280, 1024), MOUNTS[mount])
    view = Perspective(320, 240, fov, pan, tilt, roll)
    ours = view_maps(camera, view)
    mx, my = _cv_omnidir_maps(camera, view)
    cv_valid = _inside(mx, my, camera.image_size)
    both = ours.valid & cv_valid
    assert both.sum() > 0.5 * both.size
    err = np.hypot(ours.map_x - mx, ours.map_y - my)[both]
    assert err.max() < 0.05, err.max()
    assert not np.any(ours.valid & ~cv_valid)


# ---------------------------------------------------------------- beyond 180 degrees


def test_kb4_beyond_90_degrees_opencv_drops_what_the_lens_sees():
    """A 200-degree KB4 lens and a perspective view looking 95 degrees off the axis.

    The view's rays lie 50..140 degrees from the axis. omnidev maps every ray up to
    the lens's 100 degrees (finite, on the image) and masks the rest; OpenCV 5.0's
    cv2.fisheye.initUndistortRectifyMap divides by z and sets the map to +-inf for
    every ray at or beyond 90 degrees, so the 90..100-degree band the lens images
    is lost (in older OpenCV versions the same division mirrored those rays to
    the front instead).
    """
    camera = FisheyeCamera(KB4_200, (1024, 1024), MOUNTS["forward"], max_angle_deg=100.0)
    view = Perspective(400, 300, 90.0, pan_deg=95.0)
    ours = view_maps(camera, view)
    ang = _angle_from_axis_deg(camera, view.points())
    assert ang.min() == pytest.approx(50.07, abs=0.01) and ang.max() == pytest.approx(
        139.93, abs=0.01
    )
    assert np.all(np.isfinite(ours.map_x)) and np.all(np.isfinite(ours.map_y))
    assert np.array_equal(ours.valid, ang <= 100.0)  # exactly the lens's field of view
    mx, my = _cv_fisheye_maps(camera, view)
    front, band = ang < 89.9, (ang > 90.05) & (ang <= 100.0)
    assert band.sum() > 10000  # 11288 view pixels
    err = np.hypot(ours.map_x - mx, ours.map_y - my)[front]
    assert err.max() < 0.05
    assert np.all(np.isinf(mx[band]) | np.isinf(my[band]))  # OpenCV: lost
    assert np.all(_inside(ours.map_x, ours.map_y, camera.image_size)[band])  # omnidev: mapped
    # omnidev's band pixels show the right rays: unprojecting the map returns them
    rays, ok = camera.unproject(np.stack([ours.map_x[band], ours.map_y[band]], -1))
    cos = np.sum(rays * view.points()[band], axis=-1)
    assert ok.all() and np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1e-3


def test_mei_beyond_the_fold_opencv_maps_hidden_rays_onto_the_image():
    """The paracatadioptric Mei camera (xi = 1.443) images rays up to acos(-1/xi) = 133.86
    degrees from the axis (a 268-degree field); beyond it the sphere's image folds back.

    A perspective view 95 degrees off the axis reaches 140 degrees. omnidev masks
    the rays beyond the fold; cv2.omnidir.initUndistortRectifyMap maps them onto
    valid image positions, which are the images of other rays, 127-134 degrees
    from the axis: a view shows the wrong scene there, 0.26 to 12.8 degrees off.
    """
    camera = FisheyeCamera(MEI_PARA, (1280, 1024), MOUNTS["forward"])
    assert math.degrees(MEI_PARA.max_angle) == pytest.approx(133.864, abs=1e-3)
    view = Perspective(400, 300, 90.0, pan_deg=95.0)
    ours = view_maps(camera, view)
    ang = _angle_from_axis_deg(camera, view.points())
    assert np.all(np.isfinite(ours.map_x)) and np.all(np.isfinite(ours.map_y))
    assert np.all(ours.valid[ang < 133.86]) and not np.any(ours.valid[ang > 133.88])
    mx, my = _cv_omnidir_maps(camera, view)
    cv_valid = _inside(mx, my, camera.image_size)
    folded = ang > 134.0
    assert folded.sum() > 6000  # 6556 view pixels
    assert cv_valid[folded].all()  # OpenCV: every hidden ray lands on the image
    rays, ok = camera.unproject(np.stack([mx[folded], my[folded]], -1))
    assert ok.all()
    shown = _angle_from_axis_deg(camera, rays)
    assert shown.max() < 133.87 and shown.min() > 127.0  # ... on rays in front of the fold
    off = np.degrees(np.arccos(np.clip(np.sum(rays * view.points()[folded], -1), -1, 1)))
    assert off.min() > 0.2 and off.max() > 12.0
    both = ours.valid & cv_valid
    assert np.hypot(ours.map_x - mx, ours.map_y - my)[both].max() < 0.05


@pytest.mark.parametrize(
    ("lens", "size", "limit_deg"),
    [(KB4_200, (1024, 1024), 100.0), (MEI_PARA, (1280, 1024), None)],
    ids=["kb4-200deg", "mei-268deg"],
)
def test_equirectangular_beyond_180_degrees_is_finite_and_masked(lens, size, limit_deg):
    """The full sphere around a forward-looking lens: every map value finite, valid
    exactly within the field of view (and on the image), each valid pixel's ray
    recovered by unprojecting the map."""
    camera = FisheyeCamera(lens, size, MOUNTS["forward"], max_angle_deg=limit_deg)
    view = Equirectangular(360, 180)
    maps = view_maps(camera, view)
    assert np.all(np.isfinite(maps.map_x)) and np.all(np.isfinite(maps.map_y))
    ang = _angle_from_axis_deg(camera, view.points())
    fov = math.degrees(camera.max_angle)
    assert fov > 99.9
    assert not np.any(maps.valid[ang > fov + 1e-4])
    inside = (ang < fov - 0.05) & _inside(
        *camera.project(view.points())[0].transpose(2, 0, 1), size
    )
    assert np.all(maps.valid[inside])
    assert maps.valid.mean() > 0.5  # more than a hemisphere
    # unprojecting the map returns the view's rays (float32 maps: 1e-4 px; near a fold
    # where the image radius stops growing the same 1e-4 px is a larger angle)
    rays, ok = camera.unproject(np.stack([maps.map_x, maps.map_y], -1)[maps.valid])
    off = np.degrees(np.arccos(np.clip(np.sum(rays * view.points()[maps.valid], -1), -1, 1)))
    assert ok.all()
    assert off[ang[maps.valid] < fov - 2.0].max() < 1e-3 and off.max() < 0.05
