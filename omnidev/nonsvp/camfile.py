"""Calibration files of kind ``nonsvp-hyper`` and the :class:`omnidev.camera.CameraModel`
they load into, so ``omnidev unwarp --camera cam.yml`` works as for any camera kind.

File (cv2.FileStorage, YAML/XML/JSON, optionally .gz; omnidev.calibfile header):
``mirror_a, mirror_b, mirror_h, mirror_m`` (mm), ``lens_f`` (mm),
``lens_sensor_w, lens_sensor_h`` (mm), ``image_width, image_height`` (px),
``lens_kappa`` (eq. 2.8, 1/mm^2), ``lens_cx, lens_cy`` (px, optional),
``pose_pitch, pose_yaw, pose_tilt`` (rad), ``pose_tx, pose_ty, pose_tz`` (mm),
in the conventions of :mod:`omnidev.nonsvp.model` (eq. 2.13).

The camera frame of omnidev (docs/conventions.md: origin at O_m, z up) is the
mirror frame O_m of the model; lengths are millimetres, so views are given in mm
(e.g. ``top:320x240,x=4000,y=4000,z=-2000``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from omnidev.calibfile import check_header, open_storage, read_real, write_storage
from omnidev.errors import CalibrationError
from omnidev.nonsvp.forward import project
from omnidev.nonsvp.model import Lens, Mirror, NonSvpCamera, Pose

KIND = "nonsvp-hyper"
VERSION = 1

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class NonSvpCameraModel:
    """A :class:`~omnidev.nonsvp.model.NonSvpCamera` as an omnidev camera model."""

    map_bytes_per_pixel = 100.0
    """Peak bytes per output pixel of its maps (measured 59-80; see
    :func:`omnidev.camera.map_bytes_per_pixel`)."""

    def __init__(self, camera: NonSvpCamera) -> None:
        self.camera = camera

    @property
    def kind(self) -> str:
        return KIND

    @property
    def image_size(self) -> tuple[int, int]:
        w, h = self.camera.lens.size
        return int(w), int(h)

    def default_elevation_deg(self) -> tuple[float, float] | None:
        """The elevation band (deg) a panorama shows by default: from 60 degrees below
        the horizon up to the rim's elevation seen from O_m (an approximation of what
        the mirror reflects)."""
        m = self.camera.mirror
        rho = float(np.degrees(np.arctan2(m.b + m.h - m.c, m.m)))  # the rim seen from O_m
        return (-60.0, max(-30.0, min(60.0, rho)))

    def project(self, points: FloatArray, *, finite: bool) -> tuple[FloatArray, BoolArray]:
        pts = np.asarray(points, np.float64)
        shape = pts.shape[:-1]
        px, ok = project(self.camera, pts.reshape(-1, 3), finite=finite)
        w, h = self.image_size
        ok &= (
            (px[:, 0] >= -0.5) & (px[:, 0] <= w - 0.5) & (px[:, 1] >= -0.5) & (px[:, 1] <= h - 0.5)
        )
        return px.reshape((*shape, 2)), ok.reshape(shape)


def write_camera_file(path: Path, camera: NonSvpCamera, *, force: bool = False) -> None:
    """Write ``camera`` as a ``nonsvp-hyper`` calibration file (atomically)."""
    m, lens, pose = camera.mirror, camera.lens, camera.pose
    nodes: dict[str, float | int] = {
        "mirror_a": m.a,
        "mirror_b": m.b,
        "mirror_h": m.h,
        "mirror_m": m.m,
        "lens_f": lens.f,
        "lens_sensor_w": lens.sensor[0],
        "lens_sensor_h": lens.sensor[1],
        "image_width": int(lens.size[0]),
        "image_height": int(lens.size[1]),
        "lens_kappa": lens.kappa,
        "pose_pitch": pose.pitch,
        "pose_yaw": pose.yaw,
        "pose_tilt": pose.tilt,
        "pose_tx": pose.T[0],
        "pose_ty": pose.T[1],
        "pose_tz": pose.T[2],
    }
    if lens.center is not None:
        nodes["lens_cx"], nodes["lens_cy"] = lens.center
    write_storage(Path(path), KIND, VERSION, nodes, force=force)


def read_camera_file(path: Path) -> NonSvpCamera:
    """Read a ``nonsvp-hyper`` file; errors name the file and key."""
    path = Path(path)
    with open_storage(path) as fs:
        check_header(fs, path, KIND, VERSION)

        def r(key: str) -> float:
            return read_real(fs, path, key)

        center = None
        if not fs.getNode("lens_cx").empty():
            center = (r("lens_cx"), r("lens_cy"))
        try:
            mirror = Mirror(r("mirror_a"), r("mirror_b"), r("mirror_h"), r("mirror_m"))
            lens = Lens(
                r("lens_f"),
                (r("lens_sensor_w"), r("lens_sensor_h")),
                (int(r("image_width")), int(r("image_height"))),
                r("lens_kappa"),
                center,
            )
            pose = Pose(
                r("pose_pitch"), r("pose_yaw"), r("pose_tilt"),
                (r("pose_tx"), r("pose_ty"), r("pose_tz")),
            )  # fmt: skip
            return NonSvpCamera(mirror, lens, pose)
        except CalibrationError as exc:
            raise CalibrationError(f"{path}: {exc}") from None
        except ValueError as exc:
            raise CalibrationError(f"{path}: {exc}") from None


def camera_from_file(path: Path, options: Mapping[str, str]) -> NonSvpCameraModel:
    """Load a ``nonsvp-hyper`` camera (no options)."""
    if options:
        raise CalibrationError(f"nonsvp-hyper has no option {sorted(options)[0]!r}")
    return NonSvpCameraModel(read_camera_file(Path(path)))
