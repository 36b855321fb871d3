"""The camera mouse of dissertation chapter 6: pure math (numpy/OpenCV, no files or devices).

- :mod:`omnidev.mouse.landmarks`: the landmark layout (offsets from the screen corners, mm)
  and the printable landmark images.
- :mod:`omnidev.mouse.geometry`: screen corners from landmark centers, and the cursor (the
  screen point under the image center) by the dissertation's affine correction
  (eqs. 6.1-6.4) or by a homography.
- :mod:`omnidev.mouse.detect`: the detection stage of sec. 6.2.1.

Conventions: image pixels (x right, y down), origin at the center of the top-left pixel;
the monitor plane in mm (x right, y down), origin at the screen's top-left corner;
corners always in the order TL, TR, BR, BL; the cursor normalized to [0, 1] x [0, 1] of the
screen (0, 0 = top-left corner of the screen, 1, 1 = bottom-right).
"""

PREDICTIONS = ("flow", "rotation", "similarity", "translation")
"""How the camera mouse may predict landmarks out of view (``predict``): the monitor plane's
image motion, the camera's turn, a similarity of the found ones, or the dissertation's
translation (docs/camera-mouse.md)."""

DEFAULT_PREDICT = "flow"
"""The prediction the plugin, ``omnidev mouse`` and ``omnidev mouse-eval`` use unless told."""
