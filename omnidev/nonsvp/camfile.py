"""Calibration files of kind ``nonsvp-hyper`` and the :class:`omnidev.camera.CameraModel`
they load into, so ``omnidev unwarp --camera cam.yml`` works as for any camera kind.

File (cv2.FileStorage, YAML/XML/JSON, optionally .gz; omnidev.calibfile header):
``mirror_a, mirror_b, mirror_h, mirror_m`` (mm), ``lens_f`` (mm),
``lens_sensor_w, lens_sensor_h`` (mm), ``image_width, image_height`` (px),
``lens_cx, lens_cy`` (px, optional), in the conventions of :mod:`omnidev.nonsvp.model`;

- the distortion, one of: ``lens_kappa`` (eq. 2.8, 1/mm^2: ideal = (1 - kappa r_d^2)
  distorted) or ``tsai_kappa`` (Tsai's, eq. 2.12: ideal = (1 + kappa r_d^2) distorted),
  **of opposite sign**: ``lens_kappa = -tsai_kappa``;
- the pose, one of: ``pose_pitch, pose_yaw, pose_tilt`` (rad) and ``pose_tx, pose_ty,
  pose_tz`` (mm) (eq. 2.13: ``x_b = R^T x_c - T``), or Tsai's extrinsics ``tsai_R``
  (3x3 matrix) and ``tsai_T`` (3x1 matrix, mm) with ``x_c = tsai_R x_b + tsai_T`` (eq. 2.4,
  the base frame of the ring pattern; what ``omnidev nonsvp calibrate`` and Tsai's method
  produce), converted exactly by :meth:`omnidev.nonsvp.model.Pose.from_tsai`;
- ``housing_radius`` (mm, optional): the camera's body as a cylinder of this radius about
  the optical axis, from the lens centre away from the mirror. Scene points whose light
  would pass through it on the way to the mirror are not valid (the omni-image shows the
  housing there, not them).

The writer writes ``lens_kappa`` and the ``pose_*`` form (and ``housing_radius`` when set).

The camera frame of omnidev (docs/conventions.md: origin at O_m, z up) is the
mirror frame O_m of the model; lengths are millimetres, so views are given in mm
(e.g. ``top:320x240,x=4000,y=4000,z=-2000``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.calibfile import check_header, open_storage, read_mat, read_real, write_storage
from omnidev.errors import CalibrationError, naming
from omnidev.nonsvp.forward import project
from omnidev.nonsvp.model import Lens, Mirror, NonSvpCamera, Pose

KIND = "nonsvp-hyper"
VERSION = 1

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class NonSvpCameraModel:
    """A :class:`~omnidev.nonsvp.model.NonSvpCamera` as an omnidev camera model.

    ``housing_radius`` (mm, None: no housing): see the module docstring and
    :func:`housing_blocks`.
    """

    map_bytes_per_pixel = 100.0
    """Peak bytes per output pixel of its maps (measured 59-80; see
    :func:`omnidev.camera.map_bytes_per_pixel`)."""

    def __init__(self, camera: NonSvpCamera, housing_radius: float | None = None) -> None:
        self.camera = camera
        self.housing_radius = housing_radius

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
        if self.housing_radius is not None and ok.any():
            flat = pts.reshape(-1, 3)
            blocked = housing_blocks(
                self.camera, px[ok], flat[ok], self.housing_radius, finite=finite
            )
            idx = np.flatnonzero(ok)
            ok[idx[blocked]] = False
            px[idx[blocked]] = np.nan
        return px.reshape((*shape, 2)), ok.reshape(shape)


def housing_blocks(
    cam: NonSvpCamera, px: FloatArray, points: FloatArray, radius: float, *, finite: bool
) -> BoolArray:
    """(N,) True where the light from ``points`` (O_m, mm; directions if not ``finite``) to
    their mirror points, imaged at pixels ``px`` (N, 2), passes through the camera housing.

    The housing is the cylinder of ``radius`` mm about the optical axis on the far side of
    the lens plane from the mirror (the lens's front face and the body behind it). The mirror
    point M and the incident direction w of each pixel come from the back-projection; the
    segment from M along w to the point (or the whole ray for a direction) is blocked if its
    part beyond the lens plane comes within ``radius`` of the axis.
    """
    from omnidev.nonsvp.backproject import backproject

    m, w, ok = backproject(cam, px)
    o = cam.center_in_mirror()
    axis = cam.rotation_camera_to_mirror() @ np.array([0.0, 0.0, 1.0])  # towards the mirror
    rel = m - o
    s0 = rel @ axis  # height above the lens plane (> 0: the mirror's side)
    sd = w @ axis
    w0 = rel - s0[:, None] * axis
    w1 = w - sd[:, None] * axis
    t_end = np.linalg.norm(points - m, axis=1) if finite else np.full(len(px), np.inf)
    # the part of the segment t in [0, t_end] where s0 + t sd <= 0 (behind the lens plane)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_cross = np.where(sd != 0, -s0 / np.where(sd != 0, sd, 1.0), np.inf)
    lo = np.where(sd < 0, np.maximum(0.0, t_cross), 0.0)
    hi = np.where(sd > 0, np.minimum(t_end, t_cross), t_end)
    flat_ok = (sd != 0) | (s0 <= 0)  # a ray parallel to the lens plane: behind it or never
    behind = ok & flat_ok & (lo <= hi)
    aa = np.einsum("ij,ij->i", w1, w1)
    t_star = np.where(aa > 0, -np.einsum("ij,ij->i", w0, w1) / np.where(aa > 0, aa, 1.0), 0.0)
    t_star = np.minimum(np.maximum(t_star, lo), hi)
    closest = w0 + t_star[:, None] * w1
    out: BoolArray = behind & (np.einsum("ij,ij->i", closest, closest) < radius * radius)
    return out


def write_camera_file(
    path: Path,
    camera: NonSvpCamera,
    *,
    force: bool = False,
    housing_radius: float | None = None,
) -> None:
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
    if housing_radius is not None:
        nodes["housing_radius"] = float(housing_radius)
    write_storage(Path(path), KIND, VERSION, nodes, force=force)


def read_camera_file(path: Path) -> NonSvpCamera:
    """Read a ``nonsvp-hyper`` file; errors name the file and key."""
    return read_camera_and_housing(path)[0]


def _has(fs: cv2.FileStorage, key: str) -> bool:
    return not fs.getNode(key).empty()


def read_camera_and_housing(path: Path) -> tuple[NonSvpCamera, float | None]:
    """The camera of a ``nonsvp-hyper`` file and its ``housing_radius`` (None if absent)."""
    path = Path(path)
    with open_storage(path) as fs:
        check_header(fs, path, KIND, VERSION)

        def r(key: str) -> float:
            return read_real(fs, path, key)

        center = None
        if not fs.getNode("lens_cx").empty():
            center = (r("lens_cx"), r("lens_cy"))
        if _has(fs, "lens_kappa") and _has(fs, "tsai_kappa"):
            raise CalibrationError(
                f"{path}: give lens_kappa or tsai_kappa, not both (lens_kappa = -tsai_kappa)"
            )
        angles = ("pose_pitch", "pose_yaw", "pose_tilt", "pose_tx", "pose_ty", "pose_tz")
        tsai = ("tsai_R", "tsai_T")
        has_angles = [k for k in angles if _has(fs, k)]
        has_tsai = [k for k in tsai if _has(fs, k)]
        if has_angles and has_tsai:
            raise CalibrationError(
                f"{path}: give the pose as pose_* or as tsai_R, tsai_T, not both "
                f"({has_angles[0]} and {has_tsai[0]})"
            )
        housing = None
        if _has(fs, "housing_radius"):
            housing = r("housing_radius")
            if not housing > 0:
                raise CalibrationError(f"{path}: housing_radius must be > 0 mm, got {housing}")
        try:
            mirror = Mirror(r("mirror_a"), r("mirror_b"), r("mirror_h"), r("mirror_m"))
            kappa = -r("tsai_kappa") if _has(fs, "tsai_kappa") else r("lens_kappa")
            lens = Lens(
                r("lens_f"),
                (r("lens_sensor_w"), r("lens_sensor_h")),
                (int(r("image_width")), int(r("image_height"))),
                kappa,
                center,
            )
            if has_tsai:
                pose = _tsai_pose(fs, path)
            else:
                pose = Pose(
                    r("pose_pitch"), r("pose_yaw"), r("pose_tilt"),
                    (r("pose_tx"), r("pose_ty"), r("pose_tz")),
                )  # fmt: skip
            return NonSvpCamera(mirror, lens, pose), housing
        except CalibrationError as exc:
            raise CalibrationError(naming(path, exc)) from None
        except ValueError as exc:
            raise CalibrationError(f"{path}: {exc}") from None


def _tsai_pose(fs: cv2.FileStorage, path: Path) -> Pose:
    rot = np.asarray(read_mat(fs, path, "tsai_R"), np.float64)
    t = np.asarray(read_mat(fs, path, "tsai_T"), np.float64)
    if rot.shape != (3, 3):
        raise CalibrationError(f"{path}: tsai_R must be a 3x3 matrix, not {rot.shape}")
    if t.size != 3:
        raise CalibrationError(f"{path}: tsai_T must have 3 values (mm), not {t.size}")
    err = float(np.abs(rot.T @ rot - np.eye(3)).max())
    if err > 1e-6 or np.linalg.det(rot) < 0:
        raise CalibrationError(
            f"{path}: tsai_R is not a rotation (|R^T R - I| = {err:.2g}, det "
            f"{np.linalg.det(rot):+.3f})"
        )
    return Pose.from_tsai(rot, t.ravel())


def camera_from_file(path: Path, options: Mapping[str, str]) -> NonSvpCameraModel:
    """Load a ``nonsvp-hyper`` camera (no options)."""
    if options:
        raise CalibrationError(f"nonsvp-hyper has no option {sorted(options)[0]!r}")
    camera, housing = read_camera_and_housing(Path(path))
    return NonSvpCameraModel(camera, housing)
