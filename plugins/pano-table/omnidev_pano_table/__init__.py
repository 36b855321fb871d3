"""omnidev unwarper plugin for calibrations of kind ``pano-table`` (dissertation ch. 4).

The table math and file format are omnidev's public API (``omnidev.panotable``,
``omnidev.panotable.camfile``); this plugin registers them for the kind.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from omnidev.panotable.camfile import KIND, PanoTableCamera, camera_from_file

__all__ = ["PanoTableUnwarper"]


class PanoTableUnwarper:
    """Loads ``kind: pano-table`` files into :class:`omnidev.panotable.PanoTableCamera`."""

    kind = KIND

    def load(self, path: Path, options: Mapping[str, str]) -> PanoTableCamera:
        return camera_from_file(Path(path), options)
