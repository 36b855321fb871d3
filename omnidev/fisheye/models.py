"""Lens models of fisheye and central omni-cameras: optical-frame rays <-> pixels.

Every model maps (..., 3) points or directions of the **optical frame** (OpenCV's
camera frame: x right, y down, z along the optical axis, any length unit) to
(..., 2) pixels (u, v) = (column, row) with (0, 0) the centre of the top-left
pixel, and back to unit rays. Both directions return a (...) bool mask: False
where the model cannot image the ray or the pixel is not the image of any ray
(beyond the model's field of view, where its polynomial folds back, the zero
vector). Valid outputs are finite; invalid ones are NaN.

Fields of view beyond 180 degrees: angles from the optical axis are taken with
``atan2(hypot(x, y), z)``, never through ``x / z``, so rays behind the lens plane
project finitely as long as the model images them.

Models (docs/fisheye.md has the formulas):

- :class:`KannalaBrandt` (``kb4``): cv2.fisheye, Kalibr pinhole-equi, basalt kb4.
- :class:`Unified` (``mei``): Mei's unified model with radial-tangential
  distortion, as cv2.omnidir and Kalibr omni-radtan.
- :class:`IdealFisheye`: ``equidistant``, ``equisolid``, ``stereographic``,
  ``orthographic``.
- :class:`Scaramuzza` (``scaramuzza``): OCamCalib's polynomial model.
- :class:`DoubleSphere` (``ds``) and :class:`EUCM` (``eucm``): Usenko et al. 2018.
- :class:`FieldOfView` (``fov``): Devernay & Faugeras 2001, pinhole-based (z > 0 only).

Angles are radians throughout.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Literal, Protocol, get_args, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

ModelName = Literal[
    "kb4",
    "mei",
    "equidistant",
    "equisolid",
    "stereographic",
    "orthographic",
    "scaramuzza",
    "ds",
    "eucm",
    "fov",
]
MODEL_NAMES: tuple[str, ...] = get_args(ModelName)


@runtime_checkable
class LensModel(Protocol):
    """A central lens model in the optical frame (x right, y down, z forward)."""

    @property
    def name(self) -> str:
        """The model's name, one of :data:`MODEL_NAMES`."""
        ...

    @property
    def max_angle(self) -> float:
        """Largest angle from the optical axis the model images, rad (may exceed pi/2)."""
        ...

    def project(self, xyz: ArrayLike) -> tuple[FloatArray, BoolArray]:
        """(..., 3) optical-frame points or directions -> (..., 2) pixels (u, v), (...) valid."""
        ...

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, BoolArray]:
        """(..., 2) pixels (u, v) -> (..., 3) unit rays in the optical frame, (...) valid."""
        ...


# ---------------------------------------------------------------- shared helpers


def _points(xyz: ArrayLike) -> FloatArray:
    p = np.asarray(xyz, dtype=np.float64)
    if p.ndim == 0 or p.shape[-1] != 3:
        raise ValueError(f"points must have shape (..., 3), not {p.shape}")
    return p


def _pixels(uv: ArrayLike) -> FloatArray:
    q = np.asarray(uv, dtype=np.float64)
    if q.ndim == 0 or q.shape[-1] != 2:
        raise ValueError(f"pixels must have shape (..., 2), not {q.shape}")
    return q


def _angles(p: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Angle from +z (rad, [0, pi]), cos and sin of the azimuth about z, and |p|.

    At the axis (x = y = 0) the azimuth is taken as 0.
    """
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    rxy = np.hypot(x, y)
    theta = np.arctan2(rxy, z)
    safe = np.where(rxy > 0, rxy, 1.0)
    cos_az = np.where(rxy > 0, x / safe, 1.0)
    sin_az = np.where(rxy > 0, y / safe, 0.0)
    return theta, cos_az, sin_az, np.sqrt(rxy * rxy + z * z)


def _finite_rows(p: FloatArray) -> BoolArray:
    out: BoolArray = np.all(np.isfinite(p), axis=-1)
    return out


def _pack_uv(u: FloatArray, v: FloatArray, valid: BoolArray) -> tuple[FloatArray, BoolArray]:
    uv = np.stack([u, v], axis=-1)
    valid = valid & np.all(np.isfinite(uv), axis=-1)
    uv[~valid] = np.nan
    return uv, valid


def _pack_rays(
    x: FloatArray, y: FloatArray, z: FloatArray, valid: BoolArray
) -> tuple[FloatArray, BoolArray]:
    ray = np.stack([x, y, z], axis=-1)
    n = np.linalg.norm(ray, axis=-1)
    valid = valid & np.isfinite(n) & (n > 0)
    ray = ray / np.where(valid, n, 1.0)[..., None]
    ray[~valid] = np.nan
    return ray, valid


def _poly(coeffs: tuple[float, ...] | FloatArray, x: FloatArray) -> FloatArray:
    """Evaluate sum c_i x^i (ascending coefficients) by Horner's rule."""
    out = np.zeros_like(x)
    for c in reversed(tuple(coeffs)):
        out = out * x + c
    return out


def _dpoly(coeffs: tuple[float, ...] | FloatArray, x: FloatArray) -> FloatArray:
    """Derivative of :func:`_poly`."""
    c = tuple(coeffs)
    return _poly(tuple(i * c[i] for i in range(1, len(c))), x) if len(c) > 1 else np.zeros_like(x)


def first_positive_root(coeffs: tuple[float, ...], upper: float = math.inf) -> float:
    """Smallest real root in (0, upper) of sum c_i x^i (ascending); ``upper`` if none."""
    c = np.asarray(coeffs, np.float64)
    if not np.all(np.isfinite(c)):
        raise ValueError(f"polynomial coefficients are not finite: {c.tolist()}")
    scale = float(np.max(np.abs(c))) if c.size else 0.0
    keep = np.nonzero(np.abs(c) > 1e-100 * scale)[0]  # denormal leading terms are zeros
    c = c[: keep[-1] + 1] if keep.size else c[:0]
    if len(c) < 2:
        return upper
    roots = np.roots(c[::-1])
    real = roots[np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots.real))].real
    real = real[(real > 0) & (real < upper)]
    return float(real.min()) if real.size else upper


def solve_increasing(
    f: Callable[[FloatArray], FloatArray],
    df: Callable[[FloatArray], FloatArray],
    target: FloatArray,
    upper: float,
    *,
    x0: FloatArray | None = None,
    tol: float = 1e-13,
    max_iter: int = 100,
) -> tuple[FloatArray, BoolArray]:
    """Solve f(x) = target for x in [0, upper], f increasing there, vectorized.

    Newton's method kept inside a shrinking bracket [lo, hi] (a step that would
    leave the bracket is replaced by bisection), so it never diverges and never
    produces NaN for finite targets; only the entries not yet converged are
    iterated. ``x0`` is an optional start (default: linear interpolation between
    the ends). Returns x and a mask: False where the target lies outside
    [f(0), f(upper)] or the iteration did not converge.
    """
    target = np.asarray(target, np.float64)
    shape = target.shape
    f0 = float(f(np.zeros(1))[0])
    f1 = float(f(np.full(1, upper))[0])
    t_all = target.ravel()
    inside = np.isfinite(t_all) & (t_all >= f0) & (t_all <= f1)
    x_all = np.zeros_like(t_all)
    idx = np.flatnonzero(inside)
    t = t_all[idx]
    if x0 is None:
        x = upper * (t - f0) / (f1 - f0) if f1 > f0 else np.zeros_like(t)
    else:
        x = np.broadcast_to(np.asarray(x0, np.float64), shape).ravel()[idx]
    x = np.clip(np.nan_to_num(x, nan=0.0), 0.0, upper)
    lo = np.zeros_like(t)
    hi = np.full_like(t, upper)
    for _ in range(max_iter):
        if idx.size == 0:
            break
        r = f(x) - t
        lo = np.where(r <= 0, x, lo)
        hi = np.where(r >= 0, x, hi)
        d = df(x)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            xn = x - r / d
        xn = np.where(np.isfinite(xn) & (xn > lo) & (xn < hi), xn, 0.5 * (lo + hi))
        xn = np.where(r == 0, x, xn)
        done = np.abs(xn - x) <= tol * np.maximum(1.0, np.abs(xn))
        x_all[idx[done]] = xn[done]
        keep = ~done
        idx, t, x, lo, hi = idx[keep], t[keep], xn[keep], lo[keep], hi[keep]
    x_all[idx] = x  # not converged within max_iter: checked below
    scale = max(abs(f0), abs(f1), 1.0)
    ok = inside & (np.abs(f(x_all) - t_all) <= 1e-10 * scale)
    return x_all.reshape(shape), ok.reshape(shape)


def _check(name: str, **values: float) -> None:
    """ValueError naming the first parameter that is not finite or not in its range."""
    for key, value in values.items():
        if not math.isfinite(value):
            raise ValueError(f"{name} parameter {key} is not finite")
        if key in ("fx", "fy", "f", "aspect", "beta") and not value > 0:
            raise ValueError(f"{name} parameter {key} must be > 0, not {value}")
        if key == "alpha" and not 0 <= value <= 1:
            raise ValueError(f"{name} parameter alpha must be in [0, 1], not {value}")
        if key == "xi" and name == "mei" and not value >= 0:
            raise ValueError(f"mei parameter xi must be >= 0, not {value}")


def _ucm_w(alpha: float) -> float:
    """w of the unified model's valid set z > -w * |p| (alpha form; Usenko et al. 2018)."""
    return alpha / (1.0 - alpha) if alpha <= 0.5 else (1.0 - alpha) / alpha


# ---------------------------------------------------------------- Kannala-Brandt


@dataclass(frozen=True)
class KannalaBrandt:
    """Kannala-Brandt with 4 coefficients (cv2.fisheye, Kalibr pinhole-equi, basalt kb4).

    theta = angle from the optical axis, theta_d = theta (1 + k1 theta^2 + k2 theta^4
    + k3 theta^6 + k4 theta^8), (x', y') = theta_d (cos az, sin az),
    u = fx x' + skew y' + cx, v = fy y' + cy.

    ``skew`` is the camera matrix entry K[0, 1] in px (cv2.fisheye's ``alpha`` is
    ``skew / fx``). Valid: theta in [0, max_angle], where max_angle is the first
    angle at which theta_d stops growing (at most pi; the axis behind the lens,
    theta = pi exactly, is invalid since it has no azimuth).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    k: tuple[float, float, float, float]
    skew: float = 0.0

    def __post_init__(self) -> None:
        _check("kb4", fx=self.fx, fy=self.fy, cx=self.cx, cy=self.cy, skew=self.skew)
        if len(self.k) != 4:
            raise ValueError(f"kb4 needs 4 coefficients k, not {len(self.k)}")
        _check("kb4", **{f"k{i + 1}": float(v) for i, v in enumerate(self.k)})

    @property
    def name(self) -> str:
        return "kb4"

    @cached_property
    def max_angle(self) -> float:
        k1, k2, k3, k4 = self.k
        # d theta_d / d theta = 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3 + 9 k4 s^4, s = theta^2
        s = first_positive_root((1.0, 3 * k1, 5 * k2, 7 * k3, 9 * k4), math.pi**2)
        return math.sqrt(s)

    def distort(self, theta: FloatArray) -> FloatArray:
        """theta_d(theta), rad -> rad."""
        k1, k2, k3, k4 = self.k
        t2 = theta * theta
        return theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))

    def _ddistort(self, theta: FloatArray) -> FloatArray:
        k1, k2, k3, k4 = self.k
        t2 = theta * theta
        return 1.0 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))

    def project(self, xyz: ArrayLike) -> tuple[FloatArray, BoolArray]:
        p = _points(xyz)
        theta, ca, sa, n = _angles(p)
        valid = _finite_rows(p) & (n > 0) & (theta <= self.max_angle) & (theta < math.pi)
        td = self.distort(theta)
        xd, yd = td * ca, td * sa
        return _pack_uv(self.fx * xd + self.skew * yd + self.cx, self.fy * yd + self.cy, valid)

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, BoolArray]:
        q = _pixels(uv)
        yd = (q[..., 1] - self.cy) / self.fy
        xd = (q[..., 0] - self.cx - self.skew * yd) / self.fx
        td = np.hypot(xd, yd)
        theta, ok = solve_increasing(self.distort, self._ddistort, td, self.max_angle, x0=td)
        safe = np.where(td > 0, td, 1.0)
        s = np.sin(theta)
        x = np.where(td > 0, s * xd / safe, 0.0)
        y = np.where(td > 0, s * yd / safe, 0.0)
        return _pack_rays(x, y, np.cos(theta), ok)


# ---------------------------------------------------------------- unified (Mei)


@dataclass(frozen=True)
class Unified:
    """Mei's unified model with radial-tangential distortion (cv2.omnidir, Kalibr omni-radtan).

    p_s = p / |p|; (x, y) = (x_s, y_s) / (z_s + xi); r^2 = x^2 + y^2;
    x_d = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2),
    y_d = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y;
    u = fx x_d + skew y_d + cx, v = fy y_d + cy (``skew`` = K[0, 1], px).

    Valid (Mei 2007; Usenko et al. 2018): z_s > -w with w = xi for xi <= 1 and
    1 / xi for xi > 1 (beyond it the sphere's image folds back), and r below the
    first radius where r (1 + k1 r^2 + k2 r^4) stops growing.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    xi: float
    skew: float = 0.0
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0

    def __post_init__(self) -> None:
        _check("mei", fx=self.fx, fy=self.fy, cx=self.cx, cy=self.cy, xi=self.xi,
               skew=self.skew, k1=self.k1, k2=self.k2, p1=self.p1, p2=self.p2)  # fmt: skip

    @property
    def name(self) -> str:
        return "mei"

    @property
    def _w(self) -> float:
        return self.xi if self.xi <= 1.0 else 1.0 / self.xi

    @cached_property
    def r_max(self) -> float:
        """Largest undistorted normalized radius the radial distortion keeps monotonic."""
        s = first_positive_root((1.0, 3 * self.k1, 5 * self.k2))
        return math.sqrt(s) if math.isfinite(s) else math.inf

    @cached_property
    def max_angle(self) -> float:
        a = math.acos(-self._w)
        if math.isfinite(self.r_max):
            # r(angle) = sin / (cos + xi) increases with the angle on [0, a)
            def r_of(t: float) -> float:
                return math.sin(t) / (math.cos(t) + self.xi)

            if a >= math.pi or r_of(a * (1 - 1e-12)) > self.r_max:
                lo, hi = 0.0, min(a, math.pi)
                for _ in range(200):
                    mid = 0.5 * (lo + hi)
                    lo, hi = (mid, hi) if r_of(mid) < self.r_max else (lo, mid)
                a = lo
        return a

    def distort(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Radial-tangential distortion of normalized coordinates."""
        r2 = x * x + y * y
        rad = 1.0 + r2 * (self.k1 + self.k2 * r2)
        xd = x * rad + 2 * self.p1 * x * y + self.p2 * (r2 + 2 * x * x)
        yd = y * rad + self.p1 * (r2 + 2 * y * y) + 2 * self.p2 * x * y
        return xd, yd

    def undistort(
        self, xd: FloatArray, yd: FloatArray, *, max_iter: int = 40
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Invert :meth:`distort` by vectorized 2-D Newton; mask = converged and monotonic."""
        x, y = xd.copy(), yd.copy()
        k1, k2, p1, p2 = self.k1, self.k2, self.p1, self.p2
        if k1 == k2 == p1 == p2 == 0.0:
            return x, y, np.isfinite(x) & np.isfinite(y)
        for _ in range(max_iter):
            ex, ey = self.distort(x, y)
            ex, ey = ex - xd, ey - yd
            r2 = x * x + y * y
            rad = 1.0 + r2 * (k1 + k2 * r2)
            g = 2 * k1 + 4 * k2 * r2
            a = rad + g * x * x + 2 * p1 * y + 6 * p2 * x
            b = g * x * y + 2 * p1 * x + 2 * p2 * y
            d = rad + g * y * y + 6 * p1 * y + 2 * p2 * x
            det = a * d - b * b
            with np.errstate(divide="ignore", invalid="ignore"):
                dx = (d * ex - b * ey) / det
                dy = (a * ey - b * ex) / det
            bad = ~np.isfinite(dx) | ~np.isfinite(dy)
            # limit a step to the current radius + 0.5 so a poor start cannot fly off
            step = np.hypot(dx, dy)
            lim = 0.5 + np.hypot(x, y)
            f = np.where(step > lim, lim / np.where(step > 0, step, 1.0), 1.0)
            x = np.where(bad, x, x - f * dx)
            y = np.where(bad, y, y - f * dy)
            if np.all(bad | (step <= 1e-15 * (1.0 + lim))):
                break
        ex, ey = self.distort(x, y)
        ok = (np.hypot(ex - xd, ey - yd) <= 1e-11 * (1.0 + np.hypot(xd, yd))) & (
            np.hypot(x, y) <= self.r_max * (1 + 1e-9)
        )
        return x, y, ok

    def project(self, xyz: ArrayLike) -> tuple[FloatArray, BoolArray]:
        p = _points(xyz)
        n = np.linalg.norm(p, axis=-1)
        safe = np.where(n > 0, n, 1.0)
        xs, ys, zs = p[..., 0] / safe, p[..., 1] / safe, p[..., 2] / safe
        den = zs + self.xi
        valid = _finite_rows(p) & (n > 0) & (zs > -self._w) & (den > 0)
        den = np.where(valid, den, 1.0)
        x, y = xs / den, ys / den
        valid &= np.hypot(x, y) <= self.r_max * (1 + 1e-9)
        xd, yd = self.distort(x, y)
        return _pack_uv(self.fx * xd + self.skew * yd + self.cx, self.fy * yd + self.cy, valid)

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, BoolArray]:
        q = _pixels(uv)
        yd = (q[..., 1] - self.cy) / self.fy
        xd = (q[..., 0] - self.cx - self.skew * yd) / self.fx
        x, y, ok = self.undistort(xd, yd)
        r2 = x * x + y * y
        disc = 1.0 + (1.0 - self.xi * self.xi) * r2
        ok &= disc >= 0
        fac = (self.xi + np.sqrt(np.where(ok, disc, 0.0))) / (r2 + 1.0)
        zs = fac - self.xi
        ok &= zs > -self._w - 1e-12
        return _pack_rays(fac * x, fac * y, zs, ok)


# ---------------------------------------------------------------- ideal fisheyes

_IDEAL_MAX = {
    "equidistant": math.pi,
    "equisolid": math.pi,
    "stereographic": math.pi,
    "orthographic": math.pi / 2,
}


@dataclass(frozen=True)
class IdealFisheye:
    """An ideal fisheye lens: image radius r(theta) of the angle theta from the axis.

    equidistant r = f theta (theta <= pi), equisolid r = 2 f sin(theta / 2)
    (theta <= pi), stereographic r = 2 f tan(theta / 2) (theta < pi), orthographic
    r = f sin(theta) (theta <= pi / 2). u = cx + r cos(az), v = cy + aspect r sin(az):
    ``f`` is px/rad along u, ``aspect * f`` along v. The axis behind the lens
    (theta = pi) is invalid: it has no azimuth.
    """

    projection: Literal["equidistant", "equisolid", "stereographic", "orthographic"]
    f: float
    cx: float
    cy: float
    aspect: float = 1.0

    def __post_init__(self) -> None:
        if self.projection not in _IDEAL_MAX:
            raise ValueError(f"unknown ideal projection {self.projection!r}")
        _check(self.projection, f=self.f, cx=self.cx, cy=self.cy, aspect=self.aspect)

    @property
    def name(self) -> str:
        return self.projection

    @property
    def max_angle(self) -> float:
        return _IDEAL_MAX[self.projection]

    def radius(self, theta: FloatArray) -> FloatArray:
        """r(theta) in px along u (theta in rad)."""
        f = self.f
        if self.projection == "equidistant":
            return f * theta
        if self.projection == "equisolid":
            return 2 * f * np.sin(theta / 2)
        if self.projection == "stereographic":
            return 2 * f * np.tan(theta / 2)
        return f * np.sin(theta)

    def angle(self, r: FloatArray) -> tuple[FloatArray, BoolArray]:
        """theta(r) (rad) for radius r in px along u, and whether r is imaged."""
        a = r / self.f
        with np.errstate(invalid="ignore"):
            if self.projection == "equidistant":
                return a, a <= math.pi
            if self.projection == "equisolid":
                return 2 * np.arcsin(np.minimum(a / 2, 1.0)), a <= 2.0
            if self.projection == "stereographic":
                return 2 * np.arctan(a / 2), np.isfinite(a)
            return np.arcsin(np.minimum(a, 1.0)), a <= 1.0

    def project(self, xyz: ArrayLike) -> tuple[FloatArray, BoolArray]:
        p = _points(xyz)
        theta, ca, sa, n = _angles(p)
        valid = _finite_rows(p) & (n > 0) & (theta <= self.max_angle) & (theta < math.pi)
        r = self.radius(np.where(valid, theta, 0.0))
        return _pack_uv(self.cx + r * ca, self.cy + self.aspect * r * sa, valid)

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, BoolArray]:
        q = _pixels(uv)
        du = q[..., 0] - self.cx
        dv = (q[..., 1] - self.cy) / self.aspect
        r = np.hypot(du, dv)
        theta, ok = self.angle(r)
        safe = np.where(r > 0, r, 1.0)
        s = np.sin(theta)
        x = np.where(r > 0, s * du / safe, 0.0)
        y = np.where(r > 0, s * dv / safe, 0.0)
        return _pack_rays(x, y, np.cos(theta), ok & np.isfinite(theta))


# ---------------------------------------------------------------- Scaramuzza / OCamCalib


INVPOL_TOL_PX = 1.0
"""How far (px) OCamCalib's invpol may stray from the ss polynomial before a ray is masked."""


@dataclass(frozen=True)
class Scaramuzza:
    """OCamCalib's model (Scaramuzza 2006), in OCamCalib's own terms (calib_results.txt).

    OCamCalib's camera frame has x along image rows (down), y along columns (right)
    and the scene at negative z (``ss[0] < 0``). A pixel (row, col) (0-based)
    gives sensor coordinates (a, b) by [row - xc, col - yc] = [[c, d], [e, 1]] @ [a, b]
    and the ray (a, b, ss(rho)) with rho = hypot(a, b), ss(rho) = sum ss_i rho^i.
    In the optical frame (x right, y down, z forward) that ray is
    ``(x, y, z) = (b, a, -ss(rho))``: x_opt = y_ocam, y_opt = x_ocam,
    z_opt = -z_ocam (a proper rotation). So the optical axis is the ray of the
    centre (xc, yc), u = col, v = row.

    ``project`` uses ``invpol`` (world2cam: rho = sum invpol_i t^i with
    t = atan2(z_ocam, hypot(x_ocam, y_ocam)) = angle from the axis - pi / 2) when
    given, otherwise solves ss for rho (bracketed Newton). Valid: rho below the
    first radius where the angle from the axis, atan2(rho, -ss(rho)), stops growing;
    with ``invpol``, also angles up to where its radius agrees with ss within
    :data:`INVPOL_TOL_PX` (:attr:`max_angle`; so an extrapolated invpol cannot put
    rays from beyond the calibrated field onto the image).
    """

    ss: tuple[float, ...]
    xc: float
    yc: float
    c: float = 1.0
    d: float = 0.0
    e: float = 0.0
    invpol: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if len(self.ss) < 2 or not self.ss[0] < 0:
            raise ValueError("scaramuzza ss needs >= 2 coefficients and ss[0] < 0")
        _check("scaramuzza", xc=self.xc, yc=self.yc, c=self.c, d=self.d, e=self.e)
        _check("scaramuzza", **{f"ss[{i}]": float(v) for i, v in enumerate(self.ss)})
        for i, v in enumerate(self.ss):
            if not math.isfinite(i * float(v)):  # rho_max works on i * ss[i]
                raise ValueError(f"scaramuzza ss[{i}] = {v:g} is too large")
        if self.invpol is not None:
            _check("scaramuzza", **{f"invpol[{i}]": float(v) for i, v in enumerate(self.invpol)})
        if self.c - self.d * self.e == 0:
            raise ValueError("scaramuzza affine matrix [[c, d], [e, 1]] is singular")

    @property
    def name(self) -> str:
        return "scaramuzza"

    def angle(self, rho: FloatArray) -> FloatArray:
        """Angle from the optical axis (rad) of the ray at sensor radius rho."""
        return np.arctan2(rho, -_poly(self.ss, rho))

    def _dangle(self, rho: FloatArray) -> FloatArray:
        s = _poly(self.ss, rho)
        return (-s + rho * _dpoly(self.ss, rho)) / (rho * rho + s * s)

    @cached_property
    def rho_max(self) -> float:
        """Sensor radius up to which the angle from the axis grows (finite)."""
        ss = self.ss
        # d/drho atan2(rho, -ss) has the sign of -ss(rho) + rho ss'(rho)
        h = tuple([-ss[0], 0.0] + [(i - 1) * ss[i] for i in range(2, len(ss))])
        r = first_positive_root(h)
        if math.isfinite(r):
            return r
        r = abs(ss[0])
        while float(self.angle(np.array([r]))[0]) < math.pi - 1e-9 and r < 1e12:
            r *= 2.0
        return r

    @cached_property
    def max_angle(self) -> float:
        """Up to where the angle grows with rho; with ``invpol``, also where it agrees with ss.

        invpol is a fit over the calibrated image; extrapolated (rays beyond the
        image) it can return any radius, even one inside the image. The limit is the
        first angle (on a 0.05-degree grid) where its radius strays more than
        :data:`INVPOL_TOL_PX` from the ss polynomial's.
        """
        limit = float(self.angle(np.array([self.rho_max]))[0])
        if self.invpol is None:
            return limit
        alpha = np.linspace(0.0, limit, max(2, int(math.degrees(limit) / 0.05) + 1))
        rho, ok = solve_increasing(
            self.angle, self._dangle, alpha, self.rho_max, x0=-self.ss[0] * alpha
        )
        with np.errstate(invalid="ignore", over="ignore"):
            ok &= np.abs(_poly(self.invpol, alpha - math.pi / 2) - rho) <= INVPOL_TOL_PX
        bad = np.flatnonzero(~ok)
        if bad.size == 0:
            return limit
        return float(alpha[bad[0] - 1]) if bad[0] > 0 else 0.0

    def project(self, xyz: ArrayLike) -> tuple[FloatArray, BoolArray]:
        p = _points(xyz)
        alpha, ca, sa, n = _angles(p)
        valid = _finite_rows(p) & (n > 0) & (alpha <= self.max_angle) & (alpha < math.pi)
        if self.invpol is not None:
            rho = _poly(self.invpol, alpha - math.pi / 2)
        else:
            # start from the equidistant guess rho = -a0 * angle
            guess = -self.ss[0] * alpha
            rho, ok = solve_increasing(self.angle, self._dangle, alpha, self.rho_max, x0=guess)
            valid &= ok
        a, b = rho * sa, rho * ca  # OCamCalib x (rows) = optical y, y (cols) = optical x
        row = self.c * a + self.d * b + self.xc
        col = self.e * a + b + self.yc
        return _pack_uv(col, row, valid)

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, BoolArray]:
        q = _pixels(uv)
        dr, dc = q[..., 1] - self.xc, q[..., 0] - self.yc
        det = self.c - self.d * self.e
        a = (dr - self.d * dc) / det
        b = (self.c * dc - self.e * dr) / det
        rho = np.hypot(a, b)
        ok = np.isfinite(rho) & (rho <= self.rho_max)
        z = -_poly(self.ss, rho)
        if self.invpol is not None:  # the same field as project
            ok &= np.arctan2(rho, z) <= self.max_angle
        return _pack_rays(b, a, z, ok)


# ---------------------------------------------------------------- double sphere, EUCM


@dataclass(frozen=True)
class DoubleSphere:
    """Double sphere model (Usenko, Demmel, Cremers 2018; basalt/Kalibr ``ds``).

    d1 = |p|, d2 = |(x, y, xi d1 + z)|, m = alpha d2 + (1 - alpha)(xi d1 + z),
    u = fx x / m + cx, v = fy y / m + cy. Valid: z > -w2 d1 with
    w2 = (w1 + xi) / sqrt(2 w1 xi + xi^2 + 1), w1 = alpha / (1 - alpha) if
    alpha <= 0.5 else (1 - alpha) / alpha; unprojection needs
    r^2 <= 1 / (2 alpha - 1) when alpha > 0.5.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    xi: float
    alpha: float

    def __post_init__(self) -> None:
        _check("ds", fx=self.fx, fy=self.fy, cx=self.cx, cy=self.cy, xi=self.xi, alpha=self.alpha)

    @property
    def name(self) -> str:
        return "ds"

    @property
    def _w2(self) -> float:
        w1 = _ucm_w(self.alpha)
        xi = self.xi
        return (w1 + xi) / math.sqrt(2 * w1 * xi + xi * xi + 1)

    @property
    def max_angle(self) -> float:
        return math.acos(max(-1.0, min(1.0, -self._w2)))

    def project(self, xyz: ArrayLike) -> tuple[FloatArray, BoolArray]:
        p = _points(xyz)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        d1 = np.linalg.norm(p, axis=-1)
        zz = self.xi * d1 + z
        d2 = np.sqrt(x * x + y * y + zz * zz)
        m = self.alpha * d2 + (1 - self.alpha) * zz
        valid = _finite_rows(p) & (d1 > 0) & (z > -self._w2 * d1) & (m > 0)
        m = np.where(valid, m, 1.0)
        return _pack_uv(self.fx * x / m + self.cx, self.fy * y / m + self.cy, valid)

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, BoolArray]:
        q = _pixels(uv)
        mx = (q[..., 0] - self.cx) / self.fx
        my = (q[..., 1] - self.cy) / self.fy
        r2 = mx * mx + my * my
        a = self.alpha
        inner = 1 - (2 * a - 1) * r2
        ok = np.isfinite(r2) & (inner >= 0)
        mz = (1 - a * a * r2) / (a * np.sqrt(np.where(ok, inner, 0.0)) + 1 - a)
        disc = mz * mz + (1 - self.xi * self.xi) * r2
        ok &= disc >= 0
        k = (mz * self.xi + np.sqrt(np.where(ok, disc, 0.0))) / (mz * mz + r2)
        return _pack_rays(k * mx, k * my, k * mz - self.xi, ok)


@dataclass(frozen=True)
class EUCM:
    """Enhanced unified camera model (Khomutenko et al. 2016; basalt/Kalibr ``eucm``).

    d = sqrt(beta (x^2 + y^2) + z^2), m = alpha d + (1 - alpha) z,
    u = fx x / m + cx, v = fy y / m + cy. Valid: z > -w d with
    w = alpha / (1 - alpha) if alpha <= 0.5 else (1 - alpha) / alpha;
    unprojection needs r^2 <= 1 / (beta (2 alpha - 1)) when alpha > 0.5.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    alpha: float
    beta: float

    def __post_init__(self) -> None:
        _check("eucm", fx=self.fx, fy=self.fy, cx=self.cx, cy=self.cy, alpha=self.alpha,
               beta=self.beta)  # fmt: skip

    @property
    def name(self) -> str:
        return "eucm"

    @property
    def max_angle(self) -> float:
        # z = -w d  <=>  cos t = -w sqrt(beta sin^2 t + cos^2 t)
        w = _ucm_w(self.alpha)
        if w >= 1.0 and self.beta >= 1.0:
            return math.pi
        # cos^2 t (1 - w^2) = w^2 beta sin^2 t  ->  tan^2 t = (1 - w^2) / (w^2 beta)
        if w == 0:
            return math.pi / 2
        t = math.atan(math.sqrt(max(1 - w * w, 0.0) / (w * w * self.beta)))
        return math.pi - t

    def project(self, xyz: ArrayLike) -> tuple[FloatArray, BoolArray]:
        p = _points(xyz)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        d = np.sqrt(self.beta * (x * x + y * y) + z * z)
        m = self.alpha * d + (1 - self.alpha) * z
        valid = _finite_rows(p) & (d > 0) & (z > -_ucm_w(self.alpha) * d) & (m > 0)
        m = np.where(valid, m, 1.0)
        return _pack_uv(self.fx * x / m + self.cx, self.fy * y / m + self.cy, valid)

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, BoolArray]:
        q = _pixels(uv)
        mx = (q[..., 0] - self.cx) / self.fx
        my = (q[..., 1] - self.cy) / self.fy
        r2 = mx * mx + my * my
        a, b = self.alpha, self.beta
        inner = 1 - (2 * a - 1) * b * r2
        ok = np.isfinite(r2) & (inner >= 0)
        mz = (1 - b * a * a * r2) / (a * np.sqrt(np.where(ok, inner, 0.0)) + 1 - a)
        return _pack_rays(mx, my, mz, ok)


# ---------------------------------------------------------------- FOV (Devernay-Faugeras)


@dataclass(frozen=True)
class FieldOfView:
    """The FOV (``atan``) model of Devernay & Faugeras 2001 (DSO, Kalibr ``fov``, basalt ``fov``).

    On the pinhole's normalized coordinates (x_u, y_u) = (x, y) / z with r_u =
    hypot(x_u, y_u): r_d = atan(2 r_u tan(w / 2)) / w, (x_d, y_d) = (x_u, y_u) r_d / r_u,
    u = fx x_d + cx, v = fy y_d + cy (``w`` in rad, 0 < w < pi). Computed as
    r_d = atan2(2 tan(w / 2) hypot(x, y), z) / w, which is the same for z > 0.

    A pinhole-based model: valid only for rays in front of the lens plane, z > 0
    (angle from the axis < 90 degrees, :attr:`max_angle` = pi / 2), and pixels with
    r_d w < pi / 2. basalt and camera-intrinsic-model-rs evaluate the atan2 form
    behind the lens too (basalt marks those rays invalid); Devernay and Faugeras
    define it on x / z only, and so does omnidev.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    w: float

    def __post_init__(self) -> None:
        _check("fov", fx=self.fx, fy=self.fy, cx=self.cx, cy=self.cy, w=self.w)
        if not 0.0 < self.w < math.pi:
            raise ValueError(f"fov parameter w must be in (0, pi) rad, not {self.w}")

    @property
    def name(self) -> str:
        return "fov"

    @property
    def max_angle(self) -> float:
        return math.pi / 2

    @property
    def two_tan(self) -> float:
        """2 tan(w / 2)."""
        return 2.0 * math.tan(self.w / 2.0)

    def project(self, xyz: ArrayLike) -> tuple[FloatArray, BoolArray]:
        p = _points(xyz)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        rxy = np.hypot(x, y)
        valid = _finite_rows(p) & (z > 0)
        rd = np.arctan2(self.two_tan * rxy, z) / self.w
        # at the axis the scale r_d / rxy tends to 2 tan(w / 2) / (w z)
        axis = self.two_tan / (self.w * np.where(valid, z, 1.0))
        scale = np.where(rxy > 0, rd / np.where(rxy > 0, rxy, 1.0), axis)
        return _pack_uv(self.fx * x * scale + self.cx, self.fy * y * scale + self.cy, valid)

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, BoolArray]:
        q = _pixels(uv)
        mx = (q[..., 0] - self.cx) / self.fx
        my = (q[..., 1] - self.cy) / self.fy
        rd = np.hypot(mx, my)
        phi = rd * self.w  # the angle atan(2 tan(w / 2) r_u) < pi / 2
        ok = np.isfinite(rd) & (phi < math.pi / 2)
        # (x_u, y_u, 1) scaled by cos(phi): x_u = (mx / rd) tan(phi) / (2 tan(w / 2))
        safe = np.where(rd > 0, rd, 1.0)
        s = np.where(rd > 0, np.sin(phi) / (self.two_tan * safe), self.w / self.two_tan)
        return _pack_rays(mx * s, my * s, np.cos(phi), ok)
