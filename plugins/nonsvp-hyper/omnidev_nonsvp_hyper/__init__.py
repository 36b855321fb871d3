"""omnidev unwarper plugin for calibrations of kind ``nonsvp-hyper`` (dissertation ch. 2).

The camera model and file format are omnidev's public API (``omnidev.nonsvp``);
this plugin registers them for the kind, so ``omnidev unwarp --camera cam.yml``
unwarps a misaligned hyperbolic-mirror camera through its numerical forward
projection (dense maps, no unfilled pixels).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from omnidev.nonsvp.camfile import KIND, NonSvpCameraModel, camera_from_file

__all__ = ["NonSvpUnwarper"]


class NonSvpUnwarper:
    """Loads ``kind: nonsvp-hyper`` files into :class:`omnidev.nonsvp.camfile.NonSvpCameraModel`."""

    kind = KIND

    def load(self, path: Path, options: Mapping[str, str]) -> NonSvpCameraModel:
        return camera_from_file(Path(path), options)
