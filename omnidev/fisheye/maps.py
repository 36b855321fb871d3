"""Fast remap maps from a fisheye camera to a view (issue 7).

:func:`view_maps` gives the same :class:`omnidev.camera.Maps` as the plain
reference path :func:`reference_maps` (= :func:`omnidev.camera.project_maps`: the
view's (H, W, 3) float64 points, the camera's ``project``, then the packing)
to within 1e-3 px, about 15 times faster (bench/fisheye.py), by three shortcuts:

1. **Separable rays.** Every view in :mod:`omnidev.views` has rays of the form
   ``d_c(l, k) = P(l) * Q_c(k) + S_c(l)`` for each optical-frame component c
   (row l, column k): a perspective view's ray is ``M @ (x_k, y_l, 1)``, an
   equirectangular ray ``M @ (cos lat sin lon, -sin lat, cos lat cos lon)``, a
   panorama's ``mount @ (cos rho cos theta, cos rho sin theta, sin rho)``...
   with ``M = mount @ view rotation``. So the rays cost one multiply-add per
   component and pixel, computed from (H,) and (W,) vectors, not (H, W, 3)
   float64 arrays.
2. **float32 lens arithmetic** on the three (H, W) components, with the
   models' formulas (:mod:`omnidev.fisheye.models`) rearranged so that no
   ray is normalised where the model does not need it (KB4 needs one atan2, Mei
   one sqrt and one reciprocal). Maps are float32 anyway; the error this adds
   is below 1e-3 px for images up to a few thousand px.
3. **Blocks of rows** of about :data:`CHUNK` pixels, so that the temporaries
   stay in the CPU cache; ``cv2.sqrt`` and ``cv2.copyTo`` where they beat numpy.

:func:`omnidev.camera.build_maps` takes this path when the camera has a
``view_maps(view)`` method that calls :func:`view_maps`.

Models without a fast formula here (Scaramuzza without ``invpol``) and views of
other types go through the reference path. Validity follows the models: False
beyond the lens's field of view (``max_angle``, also beyond 90 degrees) or the
camera's ``max_angle_deg``, where the model folds, and outside the image.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.camera import INVALID, CameraModel, Maps, project_maps
from omnidev.fisheye.models import (
    EUCM,
    DoubleSphere,
    IdealFisheye,
    KannalaBrandt,
    LensModel,
    Scaramuzza,
    Unified,
)
from omnidev.views import (
    CylinderPanorama,
    Equirectangular,
    Panorama,
    Perspective,
    PlaneView,
    TopView,
    View,
    view_rotation,
)

F32 = NDArray[np.float32]
FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class FisheyeLike(CameraModel, Protocol):
    """What :func:`view_maps` reads of a :class:`omnidev.fisheye.camera.FisheyeCamera`."""

    @property
    def lens(self) -> LensModel: ...

    @property
    def mount(self) -> FloatArray: ...

    @property
    def max_angle_deg(self) -> float | None: ...


def reference_maps(camera: CameraModel, view: View) -> Maps:
    """The plain numpy path: float64 view points through ``camera.project``."""
    return project_maps(camera, view)


# ---------------------------------------------------------------- separable rays


def _centers(n: int, lo: float, hi: float) -> FloatArray:
    return lo + (np.arange(n, dtype=np.float64) + 0.5) * ((hi - lo) / n)


@dataclass(frozen=True)
class SeparableRays:
    """Rays of a view as (H,) and (W,) vectors, in the camera frame (before the mount).

    Component c of the ray at row l, column k is ``p[l] * q[c, k] + s[c, l]``
    (``p`` None: 1). ``norm2`` = (a (H,), b (W,)) when the squared length is
    ``a[l] + b[k]`` (a perspective view's rays (x_k, y_l, 1) rotated), ``unit``
    when every ray has length 1 (angular views); else the length is unknown.
    """

    p: FloatArray | None
    q: FloatArray
    s: FloatArray
    norm2: tuple[FloatArray, FloatArray] | None = None
    unit: bool = False


def separable_rays(
    view: View, default_elevation_deg: tuple[float, float] | None
) -> SeparableRays | None:
    """The rays (or points) of ``view`` in separable form; None for other view types."""
    if isinstance(view, Perspective):
        f = view.focal_px
        x = (np.arange(view.width) + 0.5 - view.width / 2) / f
        y = (np.arange(view.height) + 0.5 - view.height / 2) / f
        r = view.rotation()
        q = np.outer(r[:, 0], x) + r[:, 2:3]
        return SeparableRays(None, q, np.outer(r[:, 1], y), (y * y, 1.0 + x * x))
    if isinstance(view, Equirectangular):
        lon, lat = view.angles()
        r = view.rotation()
        q = np.outer(r[:, 0], np.sin(lon)) + np.outer(r[:, 2], np.cos(lon))
        return SeparableRays(np.cos(lat), q, np.outer(-r[:, 1], np.sin(lat)), unit=True)
    if isinstance(view, Panorama):
        theta, rho = view.angles(default_elevation_deg)
        q = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)])
        s = np.stack([np.zeros_like(rho), np.zeros_like(rho), np.sin(rho)])
        return SeparableRays(np.cos(rho), q, s, unit=True)
    if isinstance(view, CylinderPanorama):
        sign = -1.0 if view.clockwise else 1.0
        theta = np.radians(
            view.azimuth_start_deg + sign * _centers(view.width, 0.0, view.azimuth_span_deg)
        )
        q = view.distance * np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)])
        s = np.zeros((3, view.height))
        s[2] = _centers(view.height, view.z_top, view.z_bottom)
        return SeparableRays(None, q, s, (s[2] ** 2, np.full(view.width, view.distance**2)))
    if isinstance(view, PlaneView):
        a = math.radians(view.azimuth_deg)
        center = np.array([math.cos(a), math.sin(a), 0.0]) * view.distance
        right = np.array([math.sin(a), -math.cos(a), 0.0])
        s_k = _centers(view.width, -view.plane_width / 2, view.plane_width / 2)
        s = np.zeros((3, view.height))
        s[2] = _centers(view.height, view.z_top, view.z_bottom)
        q = center[:, None] + np.outer(right, s_k)
        return SeparableRays(None, q, s, (s[2] ** 2, view.distance**2 + s_k * s_k))
    if isinstance(view, TopView):
        x = _centers(
            view.width, view.center_x - view.extent_x / 2, view.center_x + view.extent_x / 2
        )
        y = _centers(
            view.height, view.center_y + view.extent_y / 2, view.center_y - view.extent_y / 2
        )
        q = np.zeros((3, view.width))
        q[0] = x
        s = np.stack([np.zeros_like(y), y, np.full_like(y, view.z)])
        return SeparableRays(None, q, s, (y * y + view.z**2, x * x))
    return None


def optical_blocks(
    rays: SeparableRays, mount: FloatArray, step: int
) -> Iterator[tuple[slice, F32, F32, F32, F32 | None]]:
    """Blocks of ``step`` rows: (rows, x, y, z, length) of the rays ``mount @ ray``, float32.

    x, y, z are the (h, W) optical-frame components; the length is (h, W), (1, 1)
    for unit rays, or None when the view does not give it (:class:`SeparableRays`).
    The first operand of every broadcast is a contiguous (step, W) tile, which
    numpy adds much faster than a (1, W) row.
    """
    h, w = rays.s.shape[1], rays.q.shape[1]
    qm = (mount @ rays.q).astype(np.float32)  # (3, W)
    sm = (mount @ rays.s).astype(np.float32)  # (3, H)
    step = min(step, h)
    tiles = [np.ascontiguousarray(np.broadcast_to(qm[c], (step, w))) for c in range(3)]
    p = None if rays.p is None else rays.p.astype(np.float32)[:, None]
    if rays.norm2 is not None:
        na = rays.norm2[0].astype(np.float32)[:, None]
        ntile = np.ascontiguousarray(np.broadcast_to(rays.norm2[1].astype(np.float32), (step, w)))
    for r0 in range(0, h, step):
        r1 = min(h, r0 + step)
        k = r1 - r0
        comps: list[F32] = []
        for c in range(3):
            comp = np.empty((k, w), np.float32)
            if p is None:
                np.add(tiles[c][:k], sm[c, r0:r1, None], out=comp)
            else:
                np.multiply(tiles[c][:k], p[r0:r1], out=comp)
                comp += sm[c, r0:r1, None]
            comps.append(comp)
        n: F32 | None = None
        if rays.unit:
            n = np.ones((1, 1), np.float32)
        elif rays.norm2 is not None:
            n = _sqrt(ntile[:k] + na[r0:r1])
        yield slice(r0, r1), comps[0], comps[1], comps[2], n


def _sqrt(a: F32) -> F32:
    """Elementwise square root of a float32 array (cv2's is twice as fast as numpy's)."""
    return np.asarray(cv2.sqrt(a), np.float32).reshape(a.shape)


# ---------------------------------------------------------------- fast lens formulas


def _ucm_w(alpha: float) -> float:
    """w of the unified model's valid set z > -w |p| (Usenko et al. 2018)."""
    return alpha / (1.0 - alpha) if alpha <= 0.5 else (1.0 - alpha) / alpha


def _horner(coeffs: tuple[float, ...], x: F32) -> F32:
    out = np.full_like(x, coeffs[-1])
    for c in reversed(coeffs[:-1]):
        out *= x
        out += c
    return out


def _axis_angle(x: F32, y: F32, z: F32) -> tuple[F32, F32]:
    """(hypot(x, y), angle from +z in [0, pi])."""
    rxy = np.sqrt(x * x + y * y)
    return rxy, np.arctan2(rxy, z)


def _radial_scale(radius: F32, rxy: F32) -> F32:
    """radius / rxy, 0 where rxy == 0 (the axis: x = y = 0 there anyway)."""
    out = np.zeros_like(radius)
    np.divide(radius, rxy, out=out, where=rxy > 0)
    return out


def _pixels(
    lens_fx: float, lens_fy: float, skew: float, cx: float, cy: float, xd: F32, yd: F32
) -> tuple[F32, F32]:
    """u = fx xd + skew yd + cx, v = fy yd + cy, in place where possible."""
    u = xd * np.float32(lens_fx)
    if skew:
        u += np.float32(skew) * yd
    u += np.float32(cx)
    yd *= np.float32(lens_fy)
    yd += np.float32(cy)
    return u, yd


def fast_project(
    lens: LensModel, x: F32, y: F32, z: F32, max_angle: float, n: F32 | None = None
) -> tuple[F32, F32, BoolArray] | None:
    """Pixels (u, v) and validity of optical-frame rays (x, y, z), any length, float32.

    ``max_angle`` (rad) limits the angle from the optical axis (the camera's
    limit, at most the lens's). ``n``: the rays' lengths if known (broadcastable).
    The inputs may be overwritten. None for a lens without a fast formula.
    """
    if isinstance(lens, KannalaBrandt | IdealFisheye) or (
        isinstance(lens, Scaramuzza) and lens.invpol is not None
    ):
        # angle from the axis, then a radius: everything scales x and y by radius / hypot(x, y)
        rxy2 = x * x
        rxy2 += y * y
        rxy = _sqrt(rxy2)
        theta = np.arctan2(rxy, z)
        ok = theta <= np.float32(min(max_angle, lens.max_angle))
        ok &= theta < np.float32(math.pi)
        ok &= (rxy > 0) | (z > 0)
        if isinstance(lens, KannalaBrandt):
            k1, k2, k3, k4 = lens.k
            radius = _horner((1.0, k1, k2, k3, k4), theta * theta)
            radius *= theta
        elif isinstance(lens, IdealFisheye):
            theta[~ok] = 0.0
            radius = lens.radius(theta).astype(np.float32)
        else:
            assert isinstance(lens, Scaramuzza) and lens.invpol is not None
            theta -= np.float32(math.pi / 2)
            radius = _horner(tuple(lens.invpol), theta)
        sc = _radial_scale(radius, rxy)
        x *= sc
        y *= sc
        if isinstance(lens, KannalaBrandt):
            u, v = _pixels(lens.fx, lens.fy, lens.skew, lens.cx, lens.cy, x, y)
        elif isinstance(lens, IdealFisheye):
            u, v = _pixels(1.0, lens.aspect, 0.0, lens.cx, lens.cy, x, y)
        else:
            assert isinstance(lens, Scaramuzza)
            # OCamCalib sensor (a, b) = (optical y, optical x); row = c a + d b + xc
            u = lens.e * y
            u += x
            u += np.float32(lens.yc)
            v = lens.c * y
            v += lens.d * x
            v += np.float32(lens.xc)
        return u, v, ok
    if isinstance(lens, Unified):
        if n is None:
            n = _sqrt(x * x + y * y + z * z)
        # valid: z > -w |p| (w = xi for xi <= 1, 1 / xi beyond: there the image folds);
        # it implies z + xi |p| > 0 and |p| > 0
        den = np.float32(lens.xi) * n + z
        ok = den > 0 if lens.xi <= 1.0 else np.float32(1.0 / lens.xi) * n + z > 0
        if max_angle < math.pi:
            ok &= z >= np.float32(math.cos(max_angle)) * n
        inv = np.float32(1.0) / den
        x *= inv  # x, y: normalized undistorted coordinates
        y *= inv
        xx = x * x
        yy = y * y
        r2 = xx + yy
        if math.isfinite(lens.r_max):
            ok &= r2 <= np.float32(lens.r_max**2)
        k1, k2, p1, p2 = lens.k1, lens.k2, lens.p1, lens.p2
        if p1 or p2:
            xy2 = x * y
            xy2 *= 2.0
            tx = r2 + 2.0 * xx
            tx *= p2
            tx += p1 * xy2
            ty = r2 + 2.0 * yy
            ty *= p1
            ty += p2 * xy2
        if k1 or k2:
            rad = k2 * r2
            rad += k1
            rad *= r2
            rad += 1.0
            x *= rad
            y *= rad
        if p1 or p2:
            x += tx
            y += ty
        u, v = _pixels(lens.fx, lens.fy, lens.skew, lens.cx, lens.cy, x, y)
        return u, v, ok
    if isinstance(lens, DoubleSphere):
        r2 = x * x + y * y
        d1 = np.sqrt(r2 + z * z) if n is None else n
        zz = lens.xi * d1 + z
        m = lens.alpha * np.sqrt(r2 + zz * zz) + (1 - lens.alpha) * zz
        w1 = _ucm_w(lens.alpha)
        w2 = (w1 + lens.xi) / math.sqrt(2 * w1 * lens.xi + lens.xi**2 + 1)
        ok = (z > -w2 * d1) & (m > 0)
        if max_angle < math.pi:
            ok &= z >= np.float32(math.cos(max_angle)) * d1
        inv = np.float32(1.0) / m
        x *= inv
        y *= inv
        u, v = _pixels(lens.fx, lens.fy, 0.0, lens.cx, lens.cy, x, y)
        return u, v, ok
    if isinstance(lens, EUCM):
        r2 = x * x + y * y
        d = np.sqrt(lens.beta * r2 + z * z)
        m = lens.alpha * d + (1 - lens.alpha) * z
        ok = (z > -_ucm_w(lens.alpha) * d) & (m > 0)
        if max_angle < math.pi:
            ok &= z >= np.float32(math.cos(max_angle)) * (np.sqrt(r2 + z * z) if n is None else n)
        inv = np.float32(1.0) / m
        x *= inv
        y *= inv
        u, v = _pixels(lens.fx, lens.fy, 0.0, lens.cx, lens.cy, x, y)
        return u, v, ok
    return None


CHUNK = 32768
"""Pixels per block of rows in :func:`view_maps`: the block's float32 temporaries stay in cache."""


def view_maps(camera: FisheyeLike, view: View) -> Maps:
    """Remap maps that turn images of a fisheye ``camera`` into ``view`` (fast path).

    Equal to :func:`reference_maps` within 1e-3 px (float32 arithmetic); the
    validity masks agree except for rays within ~1e-6 rad of the field-of-view
    limit or pixels within ~1e-3 px of the image border. Works through the
    view in blocks of rows of about :data:`CHUNK` pixels.
    """
    lens = camera.lens
    limit = math.pi if camera.max_angle_deg is None else math.radians(camera.max_angle_deg)
    sep = separable_rays(view, camera.default_elevation_deg())
    one = np.ones((1, 1), np.float32)
    if sep is None or fast_project(lens, one, one, one, limit) is None:
        return reference_maps(camera, view)
    mount = np.asarray(camera.mount, np.float64)
    h, w = view.height, view.width
    sw, sh = camera.image_size
    map_x = np.empty((h, w), np.float32)
    map_y = np.empty((h, w), np.float32)
    valid = np.empty((h, w), np.bool_)
    step = max(1, CHUNK // w)
    invalid = np.full((min(step, h), w), INVALID, np.float32)
    with np.errstate(all="ignore"):
        for rows, x, y, z, n in optical_blocks(sep, mount, step):
            res = fast_project(lens, x, y, z, limit, n)
            assert res is not None
            u, v, ok = res
            ok &= u >= -0.5
            ok &= u <= sw - 0.5
            ok &= v >= -0.5
            ok &= v <= sh - 0.5
            bad = (~ok).view(np.uint8)
            k = u.shape[0]
            cv2.copyTo(invalid[:k], bad, u)  # in place: u = INVALID where bad
            cv2.copyTo(invalid[:k], bad, v)
            map_x[rows] = u
            map_y[rows] = v
            valid[rows] = ok
    return Maps(map_x, map_y, valid, (sw, sh))


def rotation_for_opencv(view: Perspective | Equirectangular, mount: FloatArray) -> FloatArray:
    """The rectification rotation R that cv2 ``initUndistortRectifyMap`` needs for ``view``.

    OpenCV's maps take the ray of output pixel (k, l) as ``R^T P^-1 (k, l, 1)``
    in the optical frame; omnidev's is ``mount @ view_rotation @ (x_k, y_l, 1)``,
    so ``R = (mount @ view_rotation)^T``.
    """
    m: FloatArray = (
        np.asarray(mount, np.float64) @ view_rotation(view.pan_deg, view.tilt_deg, view.roll_deg)
    ).T
    return m


def camera_matrix_for_opencv(view: Perspective) -> FloatArray:
    """The new camera matrix P of ``view`` (principal point at the image centre, px)."""
    f = view.focal_px
    return np.array([[f, 0.0, view.width / 2 - 0.5], [0.0, f, view.height / 2 - 0.5], [0, 0, 1.0]])
