"""Views: what an unwarped image shows, as small value objects.

A view says, for every output pixel, which point (or direction) of the scene it
shows, in the *camera frame* of docs/conventions.md: origin at the camera's
viewpoint (the mirror center O_m for a catadioptric camera), z up, x and y
horizontal, right-handed; azimuth theta = atan2(y, x), elevation
rho = atan2(z, hypot(x, y)). Lengths are in the unit of the calibration
(the landmarks' unit for a pano-mapping table).

Output pixel (k, l) (column k, row l, both 0-based) samples the scene at the
*center* of its cell, i.e. at fraction (k + 0.5) / width across the view. Rows
go downwards in the scene (row 0 is the top), and columns go to the right as a
person standing at the viewpoint and looking outward sees it (clockwise seen
from above), so views are upright and not mirror-imaged.

Every view has ``points(default_elevation_deg)`` returning an (H, W, 3) float64
array. ``finite`` says whether those are points at a finite distance (planes,
cylinders) or unit directions (angular panoramas, pinhole views).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@runtime_checkable
class View(Protocol):
    """What every view provides."""

    @property
    def width(self) -> int: ...

    @property
    def height(self) -> int: ...

    @property
    def finite(self) -> bool: ...

    def points(self, default_elevation_deg: tuple[float, float] | None = None) -> FloatArray: ...


def _check_size(width: int, height: int) -> None:
    if int(width) != width or int(height) != height or width < 1 or height < 1:
        raise ValueError(f"view size must be positive integers, got {width} x {height}")


def _centers(n: int, lo: float, hi: float) -> FloatArray:
    """Cell-center samples of [lo, hi] in n cells, from lo to hi."""
    return lo + (np.arange(n, dtype=np.float64) + 0.5) * ((hi - lo) / n)


def _azimuths(width: int, start_deg: float, span_deg: float, clockwise: bool) -> FloatArray:
    sign = -1.0 if clockwise else 1.0
    return np.radians(start_deg + sign * _centers(width, 0.0, span_deg))


@dataclass(frozen=True)
class Panorama:
    """Generic (angular) panorama: columns sample azimuth, rows sample elevation linearly.

    This is the dissertation's generic panoramic image (sec. 4.2.3 A) when
    ``elevation_deg`` is the table's elevation range.

    Args:
        width, height: output size in pixels.
        elevation_deg: (bottom, top) elevation of the band in degrees; ``None``
            takes the camera's full elevation range.
        azimuth_start_deg: azimuth of the left edge of column 0, degrees.
        azimuth_span_deg: azimuth covered by the width, degrees (360 = all around).
        clockwise: columns advance clockwise seen from above (upright, not
            mirror-imaged); False follows eq. 4.9's increasing azimuth.
    """

    width: int
    height: int
    elevation_deg: tuple[float, float] | None = None
    azimuth_start_deg: float = 0.0
    azimuth_span_deg: float = 360.0
    clockwise: bool = True

    def __post_init__(self) -> None:
        _check_size(self.width, self.height)

    @property
    def finite(self) -> bool:
        return False

    def angles(
        self, default_elevation_deg: tuple[float, float] | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Azimuth per column (W,) and elevation per row (H,), radians."""
        band = self.elevation_deg or default_elevation_deg
        if band is None:
            raise ValueError("Panorama needs elevation_deg when the camera gives no default")
        bottom, top = band
        theta = _azimuths(self.width, self.azimuth_start_deg, self.azimuth_span_deg, self.clockwise)
        rho = np.radians(_centers(self.height, top, bottom))
        return theta, rho

    def points(self, default_elevation_deg: tuple[float, float] | None = None) -> FloatArray:
        theta, rho = self.angles(default_elevation_deg)
        t, r = np.meshgrid(theta, rho)
        return np.stack([np.cos(r) * np.cos(t), np.cos(r) * np.sin(t), np.sin(r)], axis=-1)


@dataclass(frozen=True)
class CylinderPanorama:
    """Specific panorama: the scene projected on a vertical cylinder (sec. 4.2.3 B).

    Args:
        width, height: output size in pixels.
        distance: cylinder radius D around the viewpoint.
        z_bottom, z_top: heights of the band's bottom and top edges relative
            to the viewpoint (the dissertation's band is z_bottom=0, z_top=H).
        azimuth_start_deg, azimuth_span_deg, clockwise: as in :class:`Panorama`.
    """

    width: int
    height: int
    distance: float
    z_bottom: float
    z_top: float
    azimuth_start_deg: float = 0.0
    azimuth_span_deg: float = 360.0
    clockwise: bool = True

    def __post_init__(self) -> None:
        _check_size(self.width, self.height)
        if not self.distance > 0:
            raise ValueError(f"CylinderPanorama distance must be > 0, got {self.distance}")

    @property
    def finite(self) -> bool:
        return True

    def points(self, default_elevation_deg: tuple[float, float] | None = None) -> FloatArray:
        theta = _azimuths(self.width, self.azimuth_start_deg, self.azimuth_span_deg, self.clockwise)
        z = _centers(self.height, self.z_top, self.z_bottom)
        t, zz = np.meshgrid(theta, z)
        d = self.distance
        return np.stack([d * np.cos(t), d * np.sin(t), zz], axis=-1)


@dataclass(frozen=True)
class PlaneView:
    """Perspective view of a vertical W x H plane (sec. 4.2.3 C).

    The plane faces the viewpoint: its center is at horizontal distance
    ``distance`` in direction ``azimuth_deg``, it spans ``plane_width``
    horizontally and heights ``z_bottom``..``z_top``.

    The dissertation gives D as the distance from O_m to the plane's two
    vertical edges (Fig. 4.6); :meth:`from_dissertation` converts.
    """

    width: int
    height: int
    distance: float
    plane_width: float
    z_bottom: float
    z_top: float
    azimuth_deg: float = 0.0

    def __post_init__(self) -> None:
        _check_size(self.width, self.height)
        if not (self.distance > 0 and self.plane_width > 0 and self.z_top != self.z_bottom):
            raise ValueError("PlaneView needs distance > 0, plane_width > 0 and z_top != z_bottom")

    @classmethod
    def from_dissertation(
        cls,
        width: int,
        height: int,
        edge_distance: float,
        plane_width: float,
        plane_height: float,
        azimuth_deg: float = 0.0,
    ) -> PlaneView:
        """The view of Fig. 4.6: edges at distance D from O_m, band 0..H."""
        if plane_width >= 2 * edge_distance:
            raise ValueError("plane_width must be < 2 * edge_distance (eq. 4.14)")
        d = math.sqrt(edge_distance**2 - (plane_width / 2) ** 2)
        return cls(width, height, d, plane_width, 0.0, plane_height, azimuth_deg)

    @property
    def finite(self) -> bool:
        return True

    def points(self, default_elevation_deg: tuple[float, float] | None = None) -> FloatArray:
        a = math.radians(self.azimuth_deg)
        center = np.array([math.cos(a), math.sin(a), 0.0]) * self.distance
        right = np.array([math.sin(a), -math.cos(a), 0.0])
        s = _centers(self.width, -self.plane_width / 2, self.plane_width / 2)
        z = _centers(self.height, self.z_top, self.z_bottom)
        ss, zz = np.meshgrid(s, z)
        pts: FloatArray = center + ss[..., None] * right
        pts[..., 2] = zz
        return pts


def plane_axes(
    center: tuple[float, float, float], normal: tuple[float, float, float], roll_deg: float = 0.0
) -> FloatArray:
    """3x3 matrix whose columns are a plane view's right, down and forward axes (camera frame).

    Forward is the plane's normal turned away from the viewpoint (the direction the viewer
    looks through the plane). Down is the world's -z projected onto the plane, so vertical
    lines on the plane are vertical in the view; on a horizontal plane (normal within 1e-9
    of vertical) it is -y, so a floor seen from above shows +x right and +y up, as
    :class:`TopView`, and a ceiling seen from below +y up and +x on the left (not
    mirror-imaged, as the viewer sees it). Right = forward x up. A positive ``roll_deg``
    turns the image clockwise as seen by the viewer (as :class:`Perspective`).

    Raises ValueError when the normal is zero or the plane passes through the viewpoint.
    """
    c = np.asarray(center, np.float64)
    n = np.asarray(normal, np.float64)
    if (
        n.shape != (3,)
        or c.shape != (3,)
        or not (np.all(np.isfinite(n)) and np.all(np.isfinite(c)))
    ):
        raise ValueError("plane center and normal must be three finite numbers each")
    norm = float(np.linalg.norm(n))
    if norm == 0:
        raise ValueError("plane normal must not be zero")
    n = n / norm
    side = float(c @ n)
    if abs(side) <= 1e-9 * max(1.0, float(np.linalg.norm(c))):
        raise ValueError("the plane passes through the viewpoint: nothing on it can be seen")
    fwd = n if side > 0 else -n
    up = np.array([0.0, 0.0, 1.0]) - fwd[2] * fwd
    if float(np.linalg.norm(up)) < 1e-9:
        up = np.array([0.0, 1.0, 0.0]) - fwd[1] * fwd
    up /= np.linalg.norm(up)
    right = np.cross(fwd, up)
    down = -up
    r = math.radians(roll_deg)
    right_r = math.cos(r) * right - math.sin(r) * down
    down_r = math.sin(r) * right + math.cos(r) * down
    return np.stack([right_r, down_r, fwd], axis=1)


@dataclass(frozen=True)
class Plane:
    """Perspective view of a rectangle on any plane: position, normal, size (issue 15).

    The rectangle is centred at ``center`` (camera frame, the calibration's unit), lies in
    the plane with normal ``normal`` (either sign), and spans ``plane_width`` along the
    view's right axis and ``plane_height`` along its down axis (:func:`plane_axes`:
    upright, not mirror-imaged, as seen from the viewpoint; ``roll_deg`` turns it). Output
    pixel (k, l) shows the plane point ``center + s_k right + t_l down`` with s_k, t_l the
    cell centres of [-w/2, w/2] and [-h/2, h/2].

    Equivalents: a vertical plane facing the viewpoint is :class:`PlaneView`
    (``center = (d cos az, d sin az, (z_bottom + z_top) / 2)``, ``normal = (cos az, sin az,
    0)``, height z_top - z_bottom); a horizontal plane below is :class:`TopView`
    (``normal = (0, 0, 1)``, ``center = (cx, cy, z)``). For a central camera (fisheye,
    pano-table) only the rays matter, so a plane view equals a :class:`Perspective` with
    the same axes up to a homography; for a non-central camera (``nonsvp-hyper``) the
    distance matters too.

    Args:
        width, height: output size in pixels.
        center: (x, y, z) of the rectangle's centre.
        normal: (x, y, z) of the plane's normal (need not be unit length).
        plane_width, plane_height: size of the rectangle (> 0).
        roll_deg: rotation of the rectangle in its plane, degrees.
    """

    width: int
    height: int
    center: tuple[float, float, float]
    normal: tuple[float, float, float]
    plane_width: float
    plane_height: float
    roll_deg: float = 0.0

    def __post_init__(self) -> None:
        _check_size(self.width, self.height)
        if not (self.plane_width > 0 and self.plane_height > 0):
            raise ValueError("Plane needs plane_width > 0 and plane_height > 0")
        object.__setattr__(self, "center", tuple(float(v) for v in self.center))
        object.__setattr__(self, "normal", tuple(float(v) for v in self.normal))
        self.axes()  # checks the plane

    @property
    def finite(self) -> bool:
        return True

    def axes(self) -> FloatArray:
        """Columns: right, down, forward (:func:`plane_axes`)."""
        return plane_axes(self.center, self.normal, self.roll_deg)

    def coordinates(self) -> tuple[FloatArray, FloatArray]:
        """Offsets along right per column (W,) and along down per row (H,)."""
        s = _centers(self.width, -self.plane_width / 2, self.plane_width / 2)
        t = _centers(self.height, -self.plane_height / 2, self.plane_height / 2)
        return s, t

    def points(self, default_elevation_deg: tuple[float, float] | None = None) -> FloatArray:
        ax = self.axes()
        s, t = self.coordinates()
        c = np.asarray(self.center, np.float64)
        pts: FloatArray = c + s[None, :, None] * ax[:, 0] + t[:, None, None] * ax[:, 1]
        return pts


def view_rotation(pan_deg: float, tilt_deg: float, roll_deg: float) -> FloatArray:
    """3x3 matrix whose columns are a view's right, down, forward axes in the camera frame.

    Forward points at azimuth ``pan_deg`` and elevation ``tilt_deg``; right is
    horizontal (clockwise of forward seen from above) before the roll; a
    positive ``roll_deg`` turns the image clockwise as seen by the viewer.
    """
    p, t, r = (math.radians(v) for v in (pan_deg, tilt_deg, roll_deg))
    fwd = np.array([math.cos(t) * math.cos(p), math.cos(t) * math.sin(p), math.sin(t)])
    right = np.array([math.sin(p), -math.cos(p), 0.0])
    down = np.cross(fwd, right)
    right_r = math.cos(r) * right - math.sin(r) * down
    down_r = math.sin(r) * right + math.cos(r) * down
    return np.stack([right_r, down_r, fwd], axis=1)


MIN_FOV_DEG = 1e-4
"""Smallest field of view of a :class:`Perspective`, degrees (a focal length of about
570,000 times the view's width)."""


@dataclass(frozen=True)
class Perspective:
    """A virtual pinhole camera at the viewpoint.

    Args:
        width, height: output size in pixels (square pixels).
        fov_deg: horizontal field of view, degrees (:data:`MIN_FOV_DEG` .. < 180).
        pan_deg: azimuth of the optical axis, degrees.
        tilt_deg: elevation of the optical axis, degrees (+ looks up).
        roll_deg: rotation about the optical axis, degrees (+ turns the image
            clockwise as seen by the viewer).
    """

    width: int
    height: int
    fov_deg: float
    pan_deg: float = 0.0
    tilt_deg: float = 0.0
    roll_deg: float = 0.0

    def __post_init__(self) -> None:
        _check_size(self.width, self.height)
        # a positive field of view so small that its focal length is not a number a map can
        # hold (the fuzz sweep's 5e-324 made tan() 0 and the maps a ZeroDivisionError)
        if not MIN_FOV_DEG <= self.fov_deg < 180:
            raise ValueError(
                f"Perspective fov_deg must be in [{MIN_FOV_DEG:g}, 180), got {self.fov_deg}"
            )

    @property
    def finite(self) -> bool:
        return False

    @property
    def focal_px(self) -> float:
        """Focal length of the virtual camera in output pixels."""
        return self.width / 2 / math.tan(math.radians(self.fov_deg) / 2)

    def rotation(self) -> FloatArray:
        """3x3 matrix whose columns are the view's right, down, forward axes in the camera frame."""
        return view_rotation(self.pan_deg, self.tilt_deg, self.roll_deg)

    def points(self, default_elevation_deg: tuple[float, float] | None = None) -> FloatArray:
        f = self.focal_px
        x = (np.arange(self.width) + 0.5 - self.width / 2) / f
        y = (np.arange(self.height) + 0.5 - self.height / 2) / f
        xx, yy = np.meshgrid(x, y)
        rays = np.stack([xx, yy, np.ones_like(xx)], axis=-1) @ self.rotation().T
        out: FloatArray = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
        return out


@dataclass(frozen=True)
class Equirectangular:
    """Longitude/latitude grid (equirectangular) around a chosen direction.

    Columns sample longitude linearly from ``lon_deg[0]`` (left edge) to
    ``lon_deg[1]`` (right edge); rows sample latitude linearly from
    ``lat_deg[1]`` (top edge) down to ``lat_deg[0]``. Longitude and latitude are
    taken in the frame of :func:`view_rotation` (pan/tilt/roll as in
    :class:`Perspective`): (lon, lat) shows the unit direction

        cos(lat) sin(lon) * right - sin(lat) * down + cos(lat) cos(lon) * forward

    so (0, 0) looks along forward, longitude grows to the right and latitude
    upwards. The default is the full sphere around +x with the poles straight
    up and down; with pan = tilt = roll = 0 it equals a 360-degree
    :class:`Panorama` over elevations -90..90 starting at azimuth 180, but
    pan/tilt/roll also put the poles elsewhere (e.g. ``tilt_deg=90`` centres
    the grid on the zenith, as suits a fisheye looking up).

    Args:
        width, height: output size in pixels.
        lon_deg: (left, right) longitudes in degrees, span in (0, 360].
        lat_deg: (bottom, top) latitudes in degrees, -90 <= bottom < top <= 90.
        pan_deg, tilt_deg, roll_deg: the centre direction and roll, degrees.
    """

    width: int
    height: int
    lon_deg: tuple[float, float] = (-180.0, 180.0)
    lat_deg: tuple[float, float] = (-90.0, 90.0)
    pan_deg: float = 0.0
    tilt_deg: float = 0.0
    roll_deg: float = 0.0

    def __post_init__(self) -> None:
        _check_size(self.width, self.height)
        lo, hi = self.lon_deg
        if not 0 < hi - lo <= 360:
            raise ValueError(f"Equirectangular lon_deg span must be in (0, 360], got {lo}:{hi}")
        bottom, top = self.lat_deg
        if not -90 <= bottom < top <= 90:
            raise ValueError(
                "Equirectangular lat_deg must satisfy -90 <= bottom < top <= 90, "
                f"got {bottom}:{top}"
            )

    @property
    def finite(self) -> bool:
        return False

    def rotation(self) -> FloatArray:
        """3x3 matrix whose columns are the grid's right, down, forward axes in the camera frame."""
        return view_rotation(self.pan_deg, self.tilt_deg, self.roll_deg)

    def angles(self) -> tuple[FloatArray, FloatArray]:
        """Longitude per column (W,) and latitude per row (H,), radians."""
        lon = np.radians(_centers(self.width, self.lon_deg[0], self.lon_deg[1]))
        lat = np.radians(_centers(self.height, self.lat_deg[1], self.lat_deg[0]))
        return lon, lat

    def points(self, default_elevation_deg: tuple[float, float] | None = None) -> FloatArray:
        lon, lat = self.angles()
        lo, la = np.meshgrid(lon, lat)
        local = np.stack([np.cos(la) * np.sin(lo), -np.sin(la), np.cos(la) * np.cos(lo)], axis=-1)
        out: FloatArray = local @ self.rotation().T
        return out


@dataclass(frozen=True)
class TopView:
    """A horizontal plane at height z seen from above, as a map.

    Image u goes to +x and image v to -y (north up when +y is north), so the
    result is the plane as seen from above, not mirror-imaged.

    Args:
        width, height: output size in pixels.
        extent_x, extent_y: size of the shown rectangle along x and y.
        z: height of the plane relative to the viewpoint (negative = below).
        center_x, center_y: center of the shown rectangle.
    """

    width: int
    height: int
    extent_x: float
    extent_y: float
    z: float
    center_x: float = 0.0
    center_y: float = 0.0

    def __post_init__(self) -> None:
        _check_size(self.width, self.height)
        if not (self.extent_x > 0 and self.extent_y > 0):
            raise ValueError("TopView extents must be > 0")

    @property
    def finite(self) -> bool:
        return True

    def points(self, default_elevation_deg: tuple[float, float] | None = None) -> FloatArray:
        x = _centers(
            self.width, self.center_x - self.extent_x / 2, self.center_x + self.extent_x / 2
        )
        y = _centers(
            self.height, self.center_y + self.extent_y / 2, self.center_y - self.extent_y / 2
        )
        xx, yy = np.meshgrid(x, y)
        return np.stack([xx, yy, np.full_like(xx, self.z)], axis=-1)


def azimuth_elevation(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Azimuth atan2(y, x) and elevation atan2(z, hypot(x, y)) of (..., 3) points, radians."""
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return np.arctan2(y, x), np.arctan2(z, np.hypot(x, y))
