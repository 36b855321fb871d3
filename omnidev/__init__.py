"""omnidev: omni-cameras as calibrated instruments and pointing devices on Linux.

The OpenCV-style API::

    import cv2, omnidev
    camera = omnidev.load_camera("camera.yml.gz")          # any registered kind
    maps = omnidev.build_maps(camera, omnidev.Panorama(2048, 512))
    panorama = omnidev.unwarp(cv2.imread("omni.png"), maps)

Conventions (pixels, frames, angles) are in docs/conventions.md.
"""

from omnidev.calibfile import load_camera
from omnidev.camera import CameraModel, Maps, Remapper, Unwarper, build_maps, unwarp
from omnidev.errors import OmnidevError
from omnidev.frame import Frame, PointerSample
from omnidev.views import (
    CylinderPanorama,
    Equirectangular,
    Panorama,
    Perspective,
    Plane,
    PlaneView,
    TopView,
    View,
)

__version__ = "0.1.0"

__all__ = [
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
]
