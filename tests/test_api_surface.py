"""The public API promised in docs/api.md: names exported and usable without the CLI."""

from __future__ import annotations

import cv2
import numpy as np

import omnidev
from omnidev.sim.fixtures import make_omni_fixture


def test_exports_are_the_documented_names():
    documented = {
        "CameraModel",
        "CylinderPanorama",
        "Equirectangular",
        "Frame",
        "Maps",
        "OmnidevError",
        "Panorama",
        "Perspective",
        "Plane",
        "PlaneView",
        "PointerSample",
        "Remapper",
        "TopView",
        "Unwarper",
        "View",
        "build_maps",
        "load_camera",
        "unwarp",
    }
    assert set(omnidev.__all__) == documented
    for name in documented:
        assert getattr(omnidev, name) is not None


def test_module_docstring_example_runs(tmp_path):
    """The three lines in omnidev's docstring, on a calibration learned here."""
    from omnidev.cli.main import main

    fixture = tmp_path / "fx"
    make_omni_fixture(fixture, size=256, frames=1, seed=3)
    calib = tmp_path / "camera.yml.gz"
    assert (
        main(
            [
                "calibrate",
                "pano-table",
                str(fixture / "landmarks.csv"),
                "--image",
                str(fixture / "omni_0000.png"),
                "--image-center",
                "detect",
                "--mirror-center",
                "0.3,-0.2,1.2",
                "-o",
                str(calib),
            ]
        )
        == 0
    )
    camera = omnidev.load_camera(str(calib))
    maps = omnidev.build_maps(camera, omnidev.Panorama(512, 128))
    panorama = omnidev.unwarp(cv2.imread(str(fixture / "omni_0000.png")), maps)
    assert panorama.shape == (128, 512, 3)
    assert maps.valid.mean() > 0.9
    assert np.std(panorama[maps.valid]) > 10  # a textured room, not a blank
