"""A fisheye (or central omni-) camera: a lens model plus its mount, as an omnidev camera.

Two frames (docs/fisheye.md, docs/conventions.md):

- the **omnidev camera frame**: origin at the lens's optical centre, z up, x and y
  horizontal, right-handed; views and landmarks live here;
- the lens's **optical frame** (OpenCV's): x right in the image, y down, z along
  the optical axis; the lens models of :mod:`omnidev.fisheye.models` live here.

The mount maps one to the other: ``x_opt = mount @ x_cam``. Its rows are
the optical axes written in the camera frame (row 0: image right, row 1: image
down, row 2: the optical axis). :data:`MOUNTS` holds the three usual ones:

- ``up`` (identity): the lens looks up (+z); image right = +x, image down = +y,
  as the mirror cameras (azimuth sign +1, docs/conventions.md);
- ``down``: the lens looks down (-z), e.g. from a ceiling; image right = +x,
  image down = -y (azimuth sign -1);
- ``forward``: the optical axis is horizontal along +x; image right = -y,
  image down = -z (the picture is upright);
- ``mirror-up``: a catadioptric camera below its mirror (the usual rig)
  calibrated with a central lens model (unified/Mei, OCamCalib): the model's
  optical axis is the ray of the image centre, which sees the camera itself
  (down), and image right = +x, image down = +y (azimuth sign +1, radius growing
  with elevation, as :class:`omnidev.sim.SvpHyperbolicCamera`). The mirror
  reverses handedness, so this mount is a reflection (determinant -1):
  diag(1, 1, -1);
- ``mirror-down``: the same rig hanging, camera above the mirror looking down:
  diag(1, -1, 1) (azimuth sign -1).

A mount is any orthonormal matrix: a rotation for a lens, a reflection for a
mirror camera whose calibration frame is the mirror image of space.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from omnidev.camera import Maps
from omnidev.fisheye.models import BoolArray, FloatArray, LensModel
from omnidev.views import View

KIND = "fisheye"

MOUNTS: dict[str, FloatArray] = {
    "up": np.eye(3),
    "down": np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
    "forward": np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]),
    "mirror-up": np.diag([1.0, 1.0, -1.0]),
    "mirror-down": np.diag([1.0, -1.0, 1.0]),
}
for _m in MOUNTS.values():
    _m.setflags(write=False)


def check_rotation(mount: FloatArray, *, tol: float = 1e-6) -> FloatArray:
    """``mount`` as a float64 3x3 matrix; ValueError unless orthonormal.

    The determinant is +1 (a rotation: a lens) or -1 (a reflection: a mirror
    camera calibrated with a lens model, see ``mirror-up``).
    """
    m = np.asarray(mount, np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise ValueError(f"mount must be a finite 3x3 matrix, not shape {m.shape}")
    if not np.allclose(m @ m.T, np.eye(3), atol=tol):
        raise ValueError("mount must be orthonormal (a rotation, or a reflection for a mirror)")
    return m


def _up_mount() -> FloatArray:
    return MOUNTS["up"]


@dataclass(frozen=True, eq=False)
class FisheyeCamera:
    """A lens model mounted in omnidev's camera frame: an :class:`omnidev.camera.CameraModel`.

    Attributes:
        lens: the lens model (optical frame).
        image_size: (width, height) of the camera's images, px.
        mount: 3x3 orthonormal matrix, ``x_opt = mount @ x_cam`` (see the module docstring).
        max_angle_deg: half field of view, deg from the optical axis, to use at most
            (e.g. to drop the lens barrel's rim); None = all the lens model images.
    """

    lens: LensModel
    image_size: tuple[int, int]
    mount: FloatArray = field(default_factory=_up_mount)
    max_angle_deg: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "mount", check_rotation(self.mount))
        if self.max_angle_deg is not None and not 0 < self.max_angle_deg <= 180:
            raise ValueError(f"max_angle_deg must be in (0, 180], not {self.max_angle_deg}")
        w, h = self.image_size
        if int(w) <= 0 or int(h) <= 0:
            raise ValueError(f"image size must be positive, not {w}x{h}")
        object.__setattr__(self, "image_size", (int(w), int(h)))

    map_bytes_per_pixel = 48.0
    """Peak bytes per output pixel of its maps (measured 16 on the fast route; see
    :func:`omnidev.camera.map_bytes_per_pixel`)."""

    @property
    def kind(self) -> str:
        return KIND

    @property
    def max_angle(self) -> float:
        """Largest angle from the optical axis the camera uses, rad."""
        a = self.lens.max_angle
        if self.max_angle_deg is not None:
            a = min(a, math.radians(self.max_angle_deg))
        return a

    @property
    def axis(self) -> FloatArray:
        """The optical axis as a unit vector of the omnidev camera frame."""
        return np.asarray(self.mount[2], np.float64)

    def _angle_ok(self, xyz_opt: FloatArray) -> BoolArray:
        if self.max_angle_deg is None:
            return np.ones(xyz_opt.shape[:-1], bool)
        theta = np.arctan2(np.hypot(xyz_opt[..., 0], xyz_opt[..., 1]), xyz_opt[..., 2])
        ok: BoolArray = theta <= math.radians(self.max_angle_deg)
        return ok

    def inside(self, uv: FloatArray) -> BoolArray:
        """Whether pixels lie on the image: [-0.5, W - 0.5] x [-0.5, H - 0.5]."""
        w, h = self.image_size
        u, v = uv[..., 0], uv[..., 1]
        ok: BoolArray = (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)
        return ok

    def project(self, points: FloatArray, *, finite: bool = True) -> tuple[FloatArray, BoolArray]:
        """(..., 3) camera-frame points or directions -> (..., 2) pixels and (...) valid.

        A central camera images a point and its direction alike, so ``finite`` does
        not matter. Valid: the lens images the ray, within ``max_angle_deg``, and
        the pixel is on the image. Invalid pixels are NaN.
        """
        p = np.asarray(points, np.float64)
        opt = p @ self.mount.T
        uv, valid = self.lens.project(opt)
        valid = valid & self._angle_ok(opt) & self.inside(np.nan_to_num(uv, nan=-1e9))
        uv[~valid] = np.nan
        return uv, valid

    def view_maps(self, view: View) -> Maps:
        """Remap maps for ``view`` by the fast float32 path (omnidev.fisheye.maps.view_maps).

        :func:`omnidev.camera.build_maps` (and so ``omnidev unwarp``) calls this; it
        equals the plain route through :meth:`project` within 1e-3 px.
        """
        from omnidev.fisheye.maps import view_maps

        return view_maps(self, view)

    def unproject(self, uv: FloatArray) -> tuple[FloatArray, BoolArray]:
        """(..., 2) pixels -> (..., 3) unit rays of the omnidev camera frame and (...) valid.

        Valid: the lens images the pixel within ``max_angle_deg`` (pixels off the
        image are unprojected too).
        """
        rays, valid = self.lens.unproject(np.asarray(uv, np.float64))
        valid = valid & self._angle_ok(np.nan_to_num(rays))
        cam = rays @ self.mount
        cam[~valid] = np.nan
        return cam, valid

    def field_angle(self) -> float:
        """Largest angle from the axis (rad) of a valid pixel on the image's border.

        For the radially monotonic lens models this is the half field of view the
        image actually covers (the border's farthest point from the axis).
        """
        w, h = self.image_size
        n = 256
        us, vs = np.linspace(-0.5, w - 0.5, n), np.linspace(-0.5, h - 0.5, n)
        border = np.concatenate(
            [
                np.stack([us, np.full(n, -0.5)], -1),
                np.stack([us, np.full(n, h - 0.5)], -1),
                np.stack([np.full(n, -0.5), vs], -1),
                np.stack([np.full(n, w - 0.5), vs], -1),
            ]
        )
        rays, ok = self.lens.unproject(border)
        inside_fov = not np.all(ok)  # some border pixel lies beyond the lens's field
        a = self.max_angle
        if ok.any() and not inside_fov:
            angles = np.arctan2(np.hypot(rays[ok, 0], rays[ok, 1]), rays[ok, 2])
            a = min(a, float(angles.max()))
        return a

    def default_elevation_deg(self) -> tuple[float, float] | None:
        """Elevation band (bottom, top), deg: the field of view around the optical axis.

        With the axis at elevation e and half field of view h (the lens's, capped by
        ``max_angle_deg`` and by the image border): (e - h, e + h) clipped to
        [-90, 90]. Up: (90 - h, 90); down: (-90, h - 90); forward: (-h, h).
        """
        e = math.degrees(math.asin(max(-1.0, min(1.0, float(self.axis[2])))))
        h = math.degrees(self.field_angle())
        return (max(-90.0, e - h), min(90.0, e + h))
