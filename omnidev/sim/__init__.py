"""Rendered omni-images with exact ground truth (deterministic from a seed).

- :class:`SvpHyperbolicCamera`: the SVP hyperbolic mirror camera of eq. 2.1.
- :class:`EquidistantFisheyeCamera`: an ideal equidistant fisheye looking up.
- :class:`RoomScene`: a textured box room with a moving shape.
- :func:`render_omni`, :func:`render_view`: the omni-image, and the true view.
- :func:`make_landmarks`: exact landmark pairs for the pano-mapping table.
"""

from omnidev.sim.fisheye import EquidistantFisheyeCamera
from omnidev.sim.landmarks import Landmark, make_landmarks, write_landmarks_csv
from omnidev.sim.mirrors import SvpHyperbolicCamera
from omnidev.sim.render import render_omni, render_view
from omnidev.sim.scene import RoomScene

__all__ = [
    "EquidistantFisheyeCamera",
    "Landmark",
    "RoomScene",
    "SvpHyperbolicCamera",
    "make_landmarks",
    "render_omni",
    "render_view",
    "write_landmarks_csv",
]
