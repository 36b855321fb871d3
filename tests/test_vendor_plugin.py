"""A camera vendor's out-of-tree plugin: built, installed, listed and used by ``omnidev unwarp``.

The plugin (tests/vendor_plugin/acme-omnicam) registers the camera kind
``acme-equidistant`` exactly as a vendor's package would. It is built and
installed with pip into a folder of its own that the test puts on PYTHONPATH,
so the test environment gains the plugin without being changed for other tests.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.conftest import REPO, psnr

PLUGIN = REPO / "tests" / "vendor_plugin" / "acme-omnicam"
F_PX, CX, CY, SIZE, MAX_DEG = 200.0, 256.3, 254.1, 512, 95.0


def pattern(theta: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """A smooth test scene painted on the sphere of directions: BGR uint8."""
    b = 128 + 100 * np.sin(4 * theta) * np.cos(3 * rho)
    g = 128 + 100 * np.cos(6 * rho + theta)
    r = 128 + 100 * np.sin(2 * theta + 5 * rho)
    return np.clip(np.stack([b, g, r], -1), 0, 255).round().astype(np.uint8)


def fisheye_image() -> np.ndarray:
    """The pattern seen by the ACME camera (each pixel's direction by the inverse model)."""
    v, u = np.mgrid[0:SIZE, 0:SIZE].astype(np.float64)
    du, dv = u - CX, v - CY
    angle = np.hypot(du, dv) / F_PX
    theta = np.arctan2(dv, du)
    img = pattern(theta, math.pi / 2 - angle)
    img[angle > math.radians(MAX_DEG)] = 0
    return img


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    target = tmp_path_factory.mktemp("vendor_site")
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--target",
            str(target),
            str(PLUGIN),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    assert list(target.glob("acme_omnicam-2.3.1.dist-info"))
    return target


def omnidev_cli(site: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(site))
    return subprocess.run(
        [sys.executable, "-m", "omnidev.cli.main", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )


def test_vendor_plugin_is_listed(installed):
    res = omnidev_cli(installed, "plugins")
    assert res.returncode == 0, res.stderr
    line = next(x for x in res.stdout.splitlines() if "acme-equidistant" in x)
    assert "acme-omnicam 2.3.1" in line and "BROKEN" not in line
    assert "pano-table" in res.stdout  # first-party plugins still there


def test_vendor_camera_kind_is_used_by_unwarp(installed, tmp_path):
    img_path = tmp_path / "fisheye.png"
    cv2.imwrite(str(img_path), fisheye_image())
    calib = tmp_path / "acme.yml"
    fs = cv2.FileStorage(str(calib), cv2.FILE_STORAGE_WRITE)
    for key, value in [
        ("kind", "acme-equidistant"),
        ("format_version", 1),
        ("f_px", F_PX),
        ("cx", CX),
        ("cy", CY),
        ("width", SIZE),
        ("height", SIZE),
        ("max_angle_deg", MAX_DEG),
    ]:
        fs.write(key, value)
    fs.release()
    out = tmp_path / "pano.png"
    res = omnidev_cli(
        installed,
        "unwarp",
        str(img_path),
        "--camera",
        str(calib),
        "--view",
        "panorama:720x160,elev=20:85",
        "-o",
        str(out),
    )
    assert res.returncode == 0, res.stderr
    pano = cv2.imread(str(out))
    assert pano.shape == (160, 720, 3)
    # truth: the pattern at every panorama pixel's direction (same view geometry)
    from omnidev.views import Panorama

    theta, rho = Panorama(720, 160, (20.0, 85.0)).angles()
    t, r = np.meshgrid(theta, rho)
    truth = pattern(t, r)
    value = psnr(pano, truth)
    assert value > 35.0, f"vendor-plugin panorama PSNR {value:.1f} dB"
