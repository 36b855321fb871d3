"""Pano-mapping table math (Algorithms 1 and 2, sec. 4.2.3) against an analytic SVP mirror."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omnidev.errors import CalibrationError, OutputError
from omnidev.panotable.camfile import PanoTableCamera, load_table, save_table
from omnidev.panotable.table import (
    PanoTable,
    calibrate,
    dissertation_plane_angles,
    fit_azimuth,
    fit_radial,
    radial,
)
from omnidev.views import PlaneView, azimuth_elevation

A, B = 28.1, 23.4
C = math.hypot(A, B)
F = 300.0
CENTER = (321.7, 318.4)


def svp_radius(rho: np.ndarray) -> np.ndarray:
    """Image radius of elevation rho for the SVP hyperbolic camera of eq. 2.1, px."""
    return F * A * A * np.cos(rho) / (2 * B * C - (B * B + C * C) * np.sin(rho))


def landmarks(n: int = 16, seed: int = 0, rot: float = 0.0, sign: int = 1):
    rng = np.random.default_rng(seed)
    theta = rng.uniform(-math.pi, math.pi, n)
    rho = np.radians(np.linspace(-70, 10, n))
    dist = rng.uniform(1.0, 3.0, n)
    xyz = np.stack([dist * np.cos(theta), dist * np.sin(theta), dist * np.tan(rho)], 1)
    r = svp_radius(rho)
    phi = sign * theta + rot
    uv = np.stack([CENTER[0] + r * np.cos(phi), CENTER[1] + r * np.sin(phi)], 1)
    mirror = np.array([0.4, -0.3, 1.2])
    return uv, xyz + mirror, mirror


def test_radial_fit_of_svp_mirror_is_subpixel():
    uv, xyz, mirror = landmarks()
    cal = calibrate(uv, xyz, mirror, CENTER, (640, 640), azimuth="identity")
    assert cal.fit.rms_px < 0.2
    # the fitted function follows the true mirror over the whole landmark band
    rho = np.radians(np.linspace(-70, 10, 500))
    assert np.max(np.abs(radial(cal.table.coeffs, rho) - svp_radius(rho))) < 0.5
    assert cal.reprojection_px.max() < 0.5


def test_fit_recovers_exact_polynomial():
    rho = np.linspace(-1.2, 0.3, 9)
    coeffs = np.array([250.0, 180.0, -20.0, 5.0, 1.5])
    fit = fit_radial(rho, radial(coeffs, rho))
    np.testing.assert_allclose(fit.coeffs, coeffs, rtol=1e-9, atol=1e-9)
    assert fit.rms_px < 1e-9


@pytest.mark.parametrize("sign,rot", [(1, 0.0), (1, 0.7), (-1, -2.0)])
def test_azimuth_fit_recovers_handedness_and_rotation(sign, rot):
    uv, xyz, mirror = landmarks(sign=sign, rot=rot)
    cal = calibrate(uv, xyz, mirror, CENTER, (640, 640), azimuth="fit")
    assert cal.table.azimuth_sign == sign
    assert abs(math.remainder(cal.table.azimuth_offset - rot, 2 * math.pi)) < 1e-9
    assert cal.reprojection_px.max() < 0.5
    _s, _phi0, res = fit_azimuth(cal.polar.theta, cal.polar.phi)
    assert np.max(np.abs(res)) < 1e-9


def test_identity_azimuth_is_wrong_for_a_rotated_world():
    uv, xyz, mirror = landmarks(rot=0.7)
    cal = calibrate(uv, xyz, mirror, CENTER, (640, 640), azimuth="identity")
    assert cal.reprojection_px.max() > 50  # residuals expose the misaligned world axes


def test_table_entries_follow_algorithm_2():
    uv, xyz, mirror = landmarks()
    t = calibrate(
        uv, xyz, mirror, CENTER, (640, 640), azimuth="identity", table_size=(720, 200)
    ).table
    assert t.table.shape == (200, 720, 2)
    i, j = 90, 57
    theta = i * 2 * math.pi / 720  # eq. 4.5
    rho = j * (t.rho_range[1] - t.rho_range[0]) / 200 + t.rho_range[0]  # eq. 4.6
    r = radial(t.coeffs, rho)  # eq. 4.8
    np.testing.assert_allclose(
        t.table[j, i], [CENTER[0] + r * math.cos(theta), CENTER[1] + r * math.sin(theta)]
    )


def test_lookups_agree_and_nearest_is_the_floor_entry():
    uv, xyz, mirror = landmarks()
    t = calibrate(uv, xyz, mirror, CENTER, (640, 640), table_size=(1440, 300)).table
    rng = np.random.default_rng(1)
    theta = rng.uniform(-math.pi, math.pi, 2000)
    rho = rng.uniform(t.rho_range[0], t.rho_range[1] - 0.01, 2000)
    exact, ok = t.lookup(theta, rho, method="analytic")
    bil, ok2 = t.lookup(theta, rho, method="bilinear")
    near, ok3 = t.lookup(theta, rho, method="nearest")
    assert ok.all() and ok2.all() and ok3.all()
    assert np.max(np.hypot(*(bil - exact).T)) < 0.01
    i = np.floor(np.mod(theta, 2 * math.pi) / (2 * math.pi / 1440)).astype(int)
    j = np.floor((rho - t.rho_range[0]) / ((t.rho_range[1] - t.rho_range[0]) / 300)).astype(int)
    np.testing.assert_array_equal(near, t.table[j, i])
    err = np.hypot(*(near - exact).T)
    assert 0.1 < np.mean(err) < 2.0  # nearest entry is up to about one table cell off


def test_outside_elevation_range_and_cutoff_are_invalid():
    uv, xyz, mirror = landmarks()
    cal = calibrate(uv, xyz, mirror, CENTER, (640, 640), cutoff_radius=40.0)
    t = cal.table
    _, ok = t.lookup(np.zeros(3), np.array([t.rho_range[0] - 0.01, t.rho_range[1] + 0.01, -1.55]))
    assert not ok.any()


def test_file_round_trip(tmp_path):
    uv, xyz, mirror = landmarks()
    cal = calibrate(uv, xyz, mirror, CENTER, (640, 640))
    p = tmp_path / "cam.yml.gz"
    save_table(p, cal)
    t = load_table(p)
    assert t.M == cal.table.M and t.N == cal.table.N
    np.testing.assert_allclose(t.coeffs, cal.table.coeffs, rtol=1e-12)
    np.testing.assert_allclose(t.table, cal.table.table, atol=1e-3)  # float32 storage
    assert t.image_center == CENTER and t.image_size == (640, 640)
    with pytest.raises(OutputError, match="exists"):
        save_table(p, cal)


def test_load_rejects_other_kind_and_version(tmp_path):
    import cv2

    for kind, version, msg in [("fisheye", 1, "kind 'fisheye'"), ("pano-table", 9, "version 9")]:
        p = tmp_path / f"{kind}{version}.yml"
        fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
        fs.write("kind", kind)
        fs.write("format_version", version)
        fs.release()
        with pytest.raises(CalibrationError, match=msg):
            load_table(p)
    with pytest.raises(CalibrationError, match="not found"):
        load_table(tmp_path / "nope.yml")
    bad = tmp_path / "bad.yml"
    bad.write_text("%YAML:1.0\nkind: [unclosed\n")
    with pytest.raises(CalibrationError, match="bad.yml"):
        load_table(bad)


@pytest.mark.parametrize(
    "rho,r,msg",
    [
        (np.linspace(-1, 0, 4), np.arange(4.0), "at least 5"),
        (np.array([-1, -1, -1, -0.5, -0.5, 0.0]), np.arange(6.0), "distinct elevations"),
        (np.array([-1, -0.5, np.nan, 0, 0.1]), np.arange(5.0), "non-finite"),
        (
            np.linspace(-0.5, -0.5 + 5e-6, 6) + np.arange(6) * 2e-6,
            np.arange(6.0),
            "ill-conditioned|distinct",
        ),
    ],
)
def test_bad_fits_are_clear_errors(rho, r, msg):
    with pytest.raises(CalibrationError, match=msg):
        fit_radial(rho, r)


def test_plane_view_is_the_dissertation_geometry():
    """PlaneView.from_dissertation samples the angles of eqs. 4.13-4.22."""
    D, W, H, MQ, NQ = 184.1, 216.3, 208.5, 64, 48
    view = PlaneView.from_dissertation(MQ, NQ, D, W, H, azimuth_deg=0.0)
    theta, rho = azimuth_elevation(view.points())
    k = np.arange(MQ) + 0.5  # our pixel centers
    l = NQ - (np.arange(NQ) + 0.5)  # rows go down, the band goes up from 0
    th_d, rho_d = dissertation_plane_angles(k[None, :], l[:, None], MQ, NQ, D, W, H)
    # the dissertation measures azimuth from the edge line O_m P_r; ours from the plane's axis
    phi = math.acos(1 - W**2 / (2 * D**2))
    np.testing.assert_allclose(theta, np.broadcast_to(phi / 2 - th_d, theta.shape), atol=1e-12)
    np.testing.assert_allclose(rho, rho_d, atol=1e-12)


def test_camera_model_projects_points_by_direction():
    uv, xyz, mirror = landmarks()
    cam = PanoTableCamera(calibrate(uv, xyz, mirror, CENTER, (640, 640)).table, "analytic")
    p = xyz - mirror
    a, ok1 = cam.project(p, finite=True)
    b, ok2 = cam.project(3.0 * p, finite=True)
    np.testing.assert_allclose(a, b)
    np.testing.assert_allclose(a, uv, atol=0.5)
    assert ok1.all() and ok2.all()
    assert isinstance(cam.table, PanoTable)
