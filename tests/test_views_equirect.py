"""The equirectangular view and its text form (issue 7)."""

from __future__ import annotations

import numpy as np
import pytest

from omnidev.views import Equirectangular, Panorama, Perspective, azimuth_elevation
from omnidev.viewspec import ViewSpecError, parse_view


def test_full_sphere_equals_the_matching_panorama():
    eq = Equirectangular(72, 36).points()
    pano = Panorama(72, 36, (-90.0, 90.0), azimuth_start_deg=180.0).points()
    assert np.abs(eq - pano).max() < 1e-12
    assert np.allclose(np.linalg.norm(eq, axis=-1), 1.0, atol=1e-12)


def test_grid_is_linear_in_longitude_and_latitude_around_the_centre_direction():
    view = Equirectangular(40, 20, (-100.0, 100.0), (-60.0, 40.0), pan_deg=30.0, tilt_deg=-25.0)
    pts = view.points()
    r = view.rotation()
    local = pts @ r  # components along right, down, forward
    lon = np.degrees(np.arctan2(local[..., 0], local[..., 2]))
    lat = np.degrees(np.arcsin(-local[..., 1]))
    # cell centres: 200 / 40 = 5 degrees per column, 100 / 20 = 5 degrees per row
    assert np.allclose(lon[0], -97.5 + 5.0 * np.arange(40), atol=1e-9)
    assert np.allclose(lat[:, 0], 37.5 - 5.0 * np.arange(20), atol=1e-9)
    # (lon, lat) = (0, 0) looks where the perspective view with the same pan/tilt looks
    fwd = Perspective(10, 10, 60.0, pan_deg=30.0, tilt_deg=-25.0).rotation()[:, 2]
    assert np.allclose(r[:, 2], fwd, atol=1e-15)
    theta, rho = azimuth_elevation(fwd)
    assert np.degrees(theta) == pytest.approx(30.0) and np.degrees(rho) == pytest.approx(-25.0)


def test_tilt_90_centres_the_grid_on_the_zenith():
    view = Equirectangular(4, 2, (-1.0, 1.0), (-1.0, 1.0), tilt_deg=90.0)
    pts = view.points()
    assert np.all(pts[..., 2] > np.cos(np.radians(1.5)))


def test_columns_go_clockwise_seen_from_above():
    pts = Equirectangular(8, 4, (-90.0, 90.0), (-10.0, 10.0)).points()
    theta, _ = azimuth_elevation(pts[1])
    assert np.all(np.diff(theta) < 0)  # azimuth decreases to the right: clockwise


def test_text_form():
    v = parse_view("equirect:1024x512")
    assert isinstance(v, Equirectangular)
    assert (v.width, v.height, v.lon_deg, v.lat_deg) == (1024, 512, (-180.0, 180.0), (-90.0, 90.0))
    v = parse_view("equirect:400x300,lon=-100:100,lat=-80:70,pan=90,tilt=10,roll=5")
    assert isinstance(v, Equirectangular)
    assert v.lon_deg == (-100.0, 100.0) and v.lat_deg == (-80.0, 70.0)
    assert (v.pan_deg, v.tilt_deg, v.roll_deg) == (90.0, 10.0, 5.0)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("equirect:100x50,lon=10:-10", "lon_deg span"),
        ("equirect:100x50,lon=-200:200", "lon_deg span"),
        ("equirect:100x50,lat=-95:0", "lat_deg"),
        ("equirect:100x50,lat=0", "lat must be LO:HI"),
        ("equirect:100x50,fov=90", "unknown setting"),
    ],
)
def test_text_form_errors_name_the_setting(spec, message):
    with pytest.raises(ViewSpecError, match=message):
        parse_view(spec)
