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
   ray is normalised where the model does not need it (KB4 and FOV need one atan2,
   Mei one sqrt and one reciprocal). Maps are float32 anyway; the error this adds
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
    FieldOfView,
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
    Plane,
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
    if isinstance(view, Plane):
        ax = view.axes()
        s_k, t_l = view.coordinates()
        c = np.asarray(view.center, np.float64)
        q = c[:, None] + np.outer(ax[:, 0], s_k)
        s = np.outer(ax[:, 1], t_l)
        # |c + s right + t down|^2 = (t^2 + 2 t c.down) + (|c|^2 + s^2 + 2 s c.right)
        n_row = t_l * t_l + 2.0 * t_l * float(c @ ax[:, 1])
        n_col = float(c @ c) + s_k * s_k + 2.0 * s_k * float(c @ ax[:, 0])
        return SeparableRays(None, q, s, (n_row, n_col))
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


class Scratch:
    """Recycled float32 and bool buffers for blocks of up to ``rows`` x ``width`` pixels.

    Every block asks for its temporaries in the same order, so after the first
    block nothing is allocated: fresh (h, W) temporaries per block made glibc
    return and re-fault the same pages, which cost 5x the arithmetic.
    """

    def __init__(self, rows: int, width: int) -> None:
        self.shape = (rows, width)
        self._f: list[F32] = []
        self._b: list[BoolArray] = []
        self._i = self._j = 0
        self.k = rows

    def start(self, k: int) -> None:
        """Begin a block of ``k`` rows: all buffers are free again."""
        self._i = self._j = 0
        self.k = k

    def f(self) -> F32:
        """A float32 (k, W) buffer (uninitialised)."""
        if self._i == len(self._f):
            self._f.append(np.empty(self.shape, np.float32))
        self._i += 1
        return self._f[self._i - 1][: self.k]

    def b(self) -> BoolArray:
        """A bool (k, W) buffer (uninitialised)."""
        if self._j == len(self._b):
            self._b.append(np.empty(self.shape, np.bool_))
        self._j += 1
        return self._b[self._j - 1][: self.k]


def optical_blocks(
    rays: SeparableRays, mount: FloatArray, step: int, ws: Scratch
) -> Iterator[tuple[slice, F32, F32, F32, F32]]:
    """Blocks of ``step`` rows: (rows, x, y, z, length) of the rays ``mount @ ray``, float32.

    x, y, z are the (h, W) optical-frame components in buffers of ``ws`` (valid
    until the next block); the length is (h, W), or (1, 1) for unit rays. The
    first operand of every broadcast is a contiguous (step, W) tile, which numpy
    adds much faster than a (1, W) row.
    """
    h, w = rays.s.shape[1], rays.q.shape[1]
    qm = (mount @ rays.q).astype(np.float32)  # (3, W)
    sm = (mount @ rays.s).astype(np.float32)  # (3, H)
    step = min(step, h)
    tiles = [np.ascontiguousarray(np.broadcast_to(qm[c], (step, w))) for c in range(3)]
    p = None if rays.p is None else rays.p.astype(np.float32)[:, None]
    one = np.ones((1, 1), np.float32)
    if rays.norm2 is not None:
        na = rays.norm2[0].astype(np.float32)[:, None]
        ntile = np.ascontiguousarray(np.broadcast_to(rays.norm2[1].astype(np.float32), (step, w)))
    for r0 in range(0, h, step):
        r1 = min(h, r0 + step)
        k = r1 - r0
        ws.start(k)
        comps: list[F32] = []
        for c in range(3):
            comp = ws.f()
            if p is None:
                np.add(tiles[c][:k], sm[c, r0:r1, None], out=comp)
            else:
                np.multiply(tiles[c][:k], p[r0:r1], out=comp)
                comp += sm[c, r0:r1, None]
            comps.append(comp)
        if rays.norm2 is not None:
            n = ws.f()
            np.add(ntile[:k], na[r0:r1], out=n)
            _sqrt(n, n)
        elif rays.unit:
            n = one
        else:
            n = ws.f()
            np.multiply(comps[0], comps[0], out=n)
            n += comps[1] * comps[1]
            n += comps[2] * comps[2]
            _sqrt(n, n)
        yield slice(r0, r1), comps[0], comps[1], comps[2], n


def _sqrt(a: F32, out: F32) -> None:
    """out = sqrt(a), float32 (cv2's is twice as fast as numpy's; out may be a)."""
    if a.size and cv2.sqrt(a, out) is not out:  # cv2 writes into a matching out
        np.sqrt(a, out=out)


# ---------------------------------------------------------------- fast lens formulas


def _ucm_w(alpha: float) -> float:
    """w of the unified model's valid set z > -w |p| (Usenko et al. 2018)."""
    return alpha / (1.0 - alpha) if alpha <= 0.5 else (1.0 - alpha) / alpha


def _affine(
    fx: float, fy: float, skew: float, cx: float, cy: float, xd: F32, yd: F32, u: F32, v: F32
) -> None:
    """u = fx xd + skew yd + cx, v = fy yd + cy (u, v: outputs; xd is overwritten)."""
    np.multiply(xd, np.float32(fx), out=u)
    if skew:
        np.multiply(yd, np.float32(skew), out=xd)
        u += xd
    u += np.float32(cx)
    np.multiply(yd, np.float32(fy), out=v)
    v += np.float32(cy)


def has_fast_formula(lens: LensModel) -> bool:
    """Whether :func:`fast_project` handles ``lens`` (else the reference path is used)."""
    if isinstance(lens, Scaramuzza):
        return lens.invpol is not None
    return isinstance(
        lens, KannalaBrandt | Unified | IdealFisheye | DoubleSphere | EUCM | FieldOfView
    )


def fast_project(
    lens: LensModel,
    x: F32,
    y: F32,
    z: F32,
    n: F32,
    max_angle: float,
    ws: Scratch,
    u: F32,
    v: F32,
    ok: BoolArray,
) -> None:
    """Pixels and validity of optical-frame rays (x, y, z) of lengths n, float32, in place.

    Writes u, v (pixels) and ok (the lens images the ray within ``max_angle`` rad of
    the axis; the image border is not checked here). x, y (and buffers of ``ws``)
    are overwritten; n may be (1, 1) for unit rays. ``lens`` must pass
    :func:`has_fast_formula`.
    """
    if isinstance(lens, KannalaBrandt | IdealFisheye | Scaramuzza):
        # angle from the axis, then a radius: x and y scale by radius / hypot(x, y)
        rxy, t = ws.f(), ws.f()
        np.multiply(x, x, out=rxy)
        np.multiply(y, y, out=t)
        rxy += t
        _sqrt(rxy, rxy)
        theta = ws.f()
        np.arctan2(rxy, z, out=theta)
        limit = min(max_angle, lens.max_angle)
        if limit < math.pi:
            np.less_equal(theta, np.float32(limit), out=ok)
        else:
            np.less(theta, np.float32(math.pi), out=ok)  # the axis behind has no azimuth
        np.maximum(rxy, np.float32(1e-30), out=rxy)  # at the axis radius = 0: scale 0, not NaN
        radius = t
        if isinstance(lens, KannalaBrandt):
            th2 = ws.f()
            np.multiply(theta, theta, out=th2)
            k1, k2, k3, k4 = lens.k
            radius.fill(k4)
            for c in (k3, k2, k1, 1.0):
                radius *= th2
                radius += np.float32(c)
            radius *= theta
        elif isinstance(lens, IdealFisheye):
            theta[~ok] = 0.0
            radius[...] = lens.radius(theta.astype(np.float64))
        else:
            assert lens.invpol is not None
            theta -= np.float32(math.pi / 2)
            radius.fill(lens.invpol[-1])
            for c in reversed(lens.invpol[:-1]):
                radius *= theta
                radius += np.float32(c)
        radius /= rxy
        x *= radius
        y *= radius
        if isinstance(lens, KannalaBrandt):
            _affine(lens.fx, lens.fy, lens.skew, lens.cx, lens.cy, x, y, u, v)
        elif isinstance(lens, IdealFisheye):
            _affine(1.0, lens.aspect, 0.0, lens.cx, lens.cy, x, y, u, v)
        else:
            # OCamCalib sensor (a, b) = (optical y, optical x): row = c a + d b + xc,
            # col = e a + b + yc
            np.multiply(y, np.float32(lens.e), out=u)
            u += x
            u += np.float32(lens.yc)
            np.multiply(y, np.float32(lens.c), out=v)
            x *= np.float32(lens.d)
            v += x
            v += np.float32(lens.xc)
        return
    t = ws.f()
    if isinstance(lens, FieldOfView):
        # r_d = atan2(2 tan(w / 2) hypot(x, y), z) / w; x, y scale by r_d / hypot(x, y).
        # Valid: z > 0 (a pinhole-based model)
        np.greater(z, 0.0, out=ok)
        if max_angle < math.pi / 2:
            _within_angle(z, n, max_angle, t, ws.b(), ok)
        rxy = ws.f()
        np.multiply(x, x, out=rxy)
        np.multiply(y, y, out=t)
        rxy += t
        _sqrt(rxy, rxy)
        np.multiply(rxy, np.float32(lens.two_tan), out=t)
        np.arctan2(t, z, out=t)
        np.maximum(rxy, np.float32(1e-30), out=rxy)  # at the axis: scale 0, not NaN
        rxy *= np.float32(lens.w)
        t /= rxy
        x *= t
        y *= t
        _affine(lens.fx, lens.fy, 0.0, lens.cx, lens.cy, x, y, u, v)
        return
    if isinstance(lens, Unified):
        # valid: z > -w |p| (w = xi for xi <= 1, 1 / xi beyond: there the image folds);
        # it implies z + xi |p| > 0 and |p| > 0
        den = ws.f()
        np.multiply(n, np.float32(lens.xi), out=den)
        den += z
        if lens.xi <= 1.0:
            np.greater(den, 0.0, out=ok)
        else:
            np.multiply(n, np.float32(1.0 / lens.xi), out=t)
            t += z
            np.greater(t, 0.0, out=ok)
        if max_angle < math.pi:
            _within_angle(z, n, max_angle, t, ws.b(), ok)
        np.divide(np.float32(1.0), den, out=den)
        x *= den  # x, y: normalized undistorted coordinates
        y *= den
        xx, yy, r2 = ws.f(), ws.f(), ws.f()
        np.multiply(x, x, out=xx)
        np.multiply(y, y, out=yy)
        np.add(xx, yy, out=r2)
        if math.isfinite(lens.r_max):
            bb = ws.b()
            np.less_equal(r2, np.float32(lens.r_max**2), out=bb)
            ok &= bb
        k1, k2, p1, p2 = lens.k1, lens.k2, lens.p1, lens.p2
        tangential = bool(p1 or p2)
        if tangential:
            xy2 = ws.f()
            np.multiply(x, y, out=xy2)
            xy2 *= np.float32(2.0)
            xx *= np.float32(2.0)  # xx -> p2 (r2 + 2 x^2) + p1 2 x y
            xx += r2
            xx *= np.float32(p2)
            np.multiply(xy2, np.float32(p1), out=t)
            xx += t
            yy *= np.float32(2.0)  # yy -> p1 (r2 + 2 y^2) + p2 2 x y
            yy += r2
            yy *= np.float32(p1)
            np.multiply(xy2, np.float32(p2), out=t)
            yy += t
        if k1 or k2:
            rad = den
            np.multiply(r2, np.float32(k2), out=rad)
            rad += np.float32(k1)
            rad *= r2
            rad += np.float32(1.0)
            x *= rad
            y *= rad
        if tangential:
            x += xx
            y += yy
        _affine(lens.fx, lens.fy, lens.skew, lens.cx, lens.cy, x, y, u, v)
        return
    # double sphere and EUCM: x, y divided by a denominator m
    r2, m = ws.f(), ws.f()
    np.multiply(x, x, out=r2)
    np.multiply(y, y, out=t)
    r2 += t
    if isinstance(lens, DoubleSphere):
        zz = ws.f()
        np.multiply(n, np.float32(lens.xi), out=zz)
        zz += z  # xi d1 + z
        np.multiply(zz, zz, out=m)
        m += r2
        _sqrt(m, m)
        m *= np.float32(lens.alpha)
        zz *= np.float32(1 - lens.alpha)
        m += zz
        w1 = _ucm_w(lens.alpha)
        w = (w1 + lens.xi) / math.sqrt(2 * w1 * lens.xi + lens.xi**2 + 1)
        np.multiply(n, np.float32(w), out=t)  # valid: z > -w2 d1
    else:
        assert isinstance(lens, EUCM)
        d = ws.f()
        np.multiply(r2, np.float32(lens.beta), out=d)
        np.multiply(z, z, out=t)
        d += t
        _sqrt(d, d)
        np.multiply(d, np.float32(lens.alpha), out=m)
        np.multiply(z, np.float32(1 - lens.alpha), out=t)
        m += t
        np.multiply(d, np.float32(_ucm_w(lens.alpha)), out=t)  # valid: z > -w d
    t += z
    np.greater(t, 0.0, out=ok)
    bb = ws.b()
    np.greater(m, 0.0, out=bb)
    ok &= bb
    if max_angle < math.pi:
        _within_angle(z, n, max_angle, t, bb, ok)
    np.divide(np.float32(1.0), m, out=m)
    x *= m
    y *= m
    _affine(lens.fx, lens.fy, 0.0, lens.cx, lens.cy, x, y, u, v)


def _within_angle(z: F32, n: F32, max_angle: float, t: F32, bb: BoolArray, ok: BoolArray) -> None:
    """ok &= (angle from the axis <= max_angle), i.e. z >= cos(max_angle) |p|."""
    np.multiply(n, np.float32(math.cos(max_angle)), out=t)
    np.greater_equal(z, t, out=bb)
    ok &= bb


CHUNK = 65536
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
    if not has_fast_formula(lens):
        return reference_maps(camera, view)
    default_band = camera.default_elevation_deg() if isinstance(view, Panorama) else None
    sep = separable_rays(view, default_band)
    if sep is None:
        return reference_maps(camera, view)
    mount = np.asarray(camera.mount, np.float64)
    h, w = view.height, view.width
    sw, sh = camera.image_size
    map_x = np.empty((h, w), np.float32)
    map_y = np.empty((h, w), np.float32)
    valid = np.empty((h, w), np.bool_)
    step = min(h, max(1, CHUNK // w))
    ws = Scratch(step, w)
    invalid = np.full((step, w), INVALID, np.float32)
    # a finite view may contain the viewpoint itself: that point has no direction
    maybe_zero = sep.norm2 is not None and sep.norm2[0].min() + sep.norm2[1].min() <= 0
    with np.errstate(all="ignore"):
        for rows, x, y, z, n in optical_blocks(sep, mount, step, ws):
            u, v, ok = map_x[rows], map_y[rows], valid[rows]
            fast_project(lens, x, y, z, n, limit, ws, u, v, ok)
            bb = ws.b()
            for arr, lo, hi in ((u, -0.5, sw - 0.5), (v, -0.5, sh - 0.5)):
                np.greater_equal(arr, np.float32(lo), out=bb)
                ok &= bb
                np.less_equal(arr, np.float32(hi), out=bb)
                ok &= bb
            if maybe_zero:
                np.greater(n, 0.0, out=bb)
                ok &= bb
            np.logical_not(ok, out=bb)
            bad = bb.view(np.uint8)
            k = u.shape[0]
            cv2.copyTo(invalid[:k], bad, u)  # in place: u = INVALID where not ok
            cv2.copyTo(invalid[:k], bad, v)
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
