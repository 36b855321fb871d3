"""omnidev unwarper plugin for calibrations of kind ``fisheye`` (issue 7).

The lens models, the camera and the file format are omnidev's public API
(``omnidev.fisheye``); this plugin registers them for the kind, so
``omnidev unwarp --camera cam.yml`` unwarps fisheye and central omni-cameras.
Options (``--camera-option KEY=VALUE``): ``mount=up|down|forward`` and
``max_angle_deg=DEG``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from omnidev.fisheye.camera import KIND, FisheyeCamera
from omnidev.fisheye.camfile import camera_from_file

__all__ = ["FisheyeUnwarper"]


class FisheyeUnwarper:
    """Loads ``kind: fisheye`` files into :class:`omnidev.fisheye.camera.FisheyeCamera`."""

    kind = KIND

    def load(self, path: Path, options: Mapping[str, str]) -> FisheyeCamera:
        return camera_from_file(Path(path), options)
