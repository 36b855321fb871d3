"""Fisheye and central omni-cameras (issue 7): lens models, the camera and its file.

- ``models``: the lens models (Kannala-Brandt KB4, unified/Mei, the ideal
  equidistant/equisolid/stereographic/orthographic lenses, Scaramuzza/OCamCalib,
  double sphere, EUCM, FOV), pure numpy: optical-frame rays <-> pixels with validity
  masks, fields of view beyond 180 degrees included.
- ``camera``: :class:`~omnidev.fisheye.camera.FisheyeCamera`, a lens plus a mount
  (how the optical axis sits in omnidev's z-up camera frame): an
  :class:`omnidev.camera.CameraModel` of kind ``fisheye``.
- ``camfile``: the ``kind: fisheye`` calibration file (cv2.FileStorage).

Optical frame: OpenCV's camera frame, x right, y down, z along the optical axis.
Pixels (u, v) = (column, row), (0, 0) the centre of the top-left pixel. See
docs/fisheye.md.
"""
