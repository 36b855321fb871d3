"""The generalized pano-mapping function, beyond the dissertation's aligned, symmetric camera.

The dissertation's table (ch. 4) assumes a perfect camera: the image center is
known, pixels are square, the camera axis is the world vertical and one radial
function serves every azimuth. Its future work 7.2 (1) proposes calibrating per
azimuth when the mirror and lens are not perfect. This module fits, jointly to
the landmarks:

- the image center (u0, v0), px;
- the pixel aspect ratio ``aspect`` (v scale / u scale);
- the tilt of the camera axis against the world vertical: a rotation ``tilt``
  = (wx, wy) rad (Rodrigues vector, no z part: a turn about the axis is phi0);
- a keystone (g1, g2) in 1/px: the perspective of a lens tilted against its mirror;
- the radial function r(rho') of degree ``len(coeffs) - 1`` (4 = eq. 4.2; fitted free
  or as (rho' - pole) q(rho'), zero at the pole the image center sees), or
  the unified (sphere) model's ``gamma cos(rho') / (c + sin(rho'))`` (exact for
  an SVP hyperbolic mirror, two parameters, which keeps its shape outside the
  landmarks' elevations where a polynomial swings), plus
  an azimuth-dependent part: K harmonics in theta' whose coefficients are
  polynomials of degree D in the normalized elevation t = (rho' - mid) / half,
  for the radius (px) and for the image angle (rad).

Frames (docs/conventions.md). World: the landmarks' frame, Z up. *Table
frame*: the camera's own frame, the world frame translated to O_m and turned
by ``R = rodrigues(wx, wy, 0)``: d_table = R d_world. Angles theta', rho' are
azimuth and elevation in the table frame; the table is indexed by them, so the
table describes the camera and the tilt describes its mount.

The mapping from a table-frame direction (theta', rho') to a pixel::

    r   = sum_i a_i rho'^i + gamma cos rho' / (c + sin rho')
          + sum_k sum_i t^i (Rc_ki cos k theta' + Rs_ki sin k theta')
    phi = s theta' + phi0  + sum_k sum_i t^i (Pc_ki cos k theta' + Ps_ki sin k theta')
    x, y = r cos phi, r sin phi;  w = 1 + g1 x + g2 y
    u = u0 + x / w;  v = v0 + aspect * y / w

With every extra term at its neutral value (aspect 1, no tilt, no keystone,
degree 4, no harmonics) this is the dissertation's eqs. 4.1-4.2 with the
fitted azimuth mapping of :mod:`omnidev.panotable.table`.

Which terms are kept is chosen by the held-out landmark residual
(cross-validation over folds of landmarks, or over groups such as boards), so
that 32 landmarks do not buy 40 parameters.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

TWO_PI = 2.0 * math.pi


def rotation_from_tilt(tilt: tuple[float, float]) -> FloatArray:
    """3x3 rotation R (world -> table frame) of the Rodrigues vector (wx, wy, 0), rad."""
    wx, wy = float(tilt[0]), float(tilt[1])
    a = math.hypot(wx, wy)
    if a == 0.0:
        return np.eye(3)
    k = np.array([wx / a, wy / a, 0.0])
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.asarray(np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * (K @ K), np.float64)


def table_angles(dirs: FloatArray, tilt: tuple[float, float]) -> tuple[FloatArray, FloatArray]:
    """Azimuth and elevation (rad) in the table frame of (..., 3) world-frame points."""
    d = np.asarray(dirs, np.float64)
    if tilt[0] != 0.0 or tilt[1] != 0.0:
        d = d @ rotation_from_tilt(tilt).T
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.arctan2(y, x), np.arctan2(z, np.hypot(x, y))


@dataclass(frozen=True)
class PanoMapping:
    """A (generalized) pano mapping: table-frame direction -> pixel. See the module docstring.

    Attributes:
        coeffs: a_0..a_D of the radial polynomial, px for rho' in rad (D = 4: eq. 4.2).
        image_center: (u0, v0) px.
        azimuth_sign, azimuth_offset: s and phi0 (rad).
        aspect: v scale over u scale of the pixels (1 = square).
        keystone: (g1, g2) 1/px.
        tilt: (wx, wy) rad, world -> table frame.
        harmonics: (K, D + 1, 4) float64: for harmonic k + 1 and power i of t,
            (Rc, Rs) px and (Pc, Ps) rad; K = 0 for none.
        rho_norm: (mid, half) rad of t = (rho' - mid) / half.
        radial_base: (gamma px, c) of the unified model's term
            ``gamma cos(rho') / (c + sin(rho'))`` added to the polynomial;
            gamma = 0 for none.
    """

    coeffs: FloatArray
    image_center: tuple[float, float]
    azimuth_sign: int = 1
    azimuth_offset: float = 0.0
    aspect: float = 1.0
    keystone: tuple[float, float] = (0.0, 0.0)
    tilt: tuple[float, float] = (0.0, 0.0)
    harmonics: FloatArray = field(default_factory=lambda: np.zeros((0, 1, 4)))
    rho_norm: tuple[float, float] = (0.0, 1.0)
    radial_base: tuple[float, float] = (0.0, 0.0)

    def radial(self, rho: FloatArray) -> FloatArray:
        """The azimuth-independent radius r(rho') px of table-frame elevations rho' (rad)."""
        rho = np.asarray(rho, np.float64)
        r = np.polynomial.polynomial.polyval(rho, np.asarray(self.coeffs, np.float64))
        gamma, c = self.radial_base
        if gamma != 0.0:
            with np.errstate(divide="ignore", invalid="ignore"):
                r = r + gamma * np.cos(rho) / (c + np.sin(rho))
        return np.asarray(r, np.float64)

    @property
    def is_dissertation(self) -> bool:
        """True when every extra term is neutral (the dissertation's eqs. 4.1-4.2)."""
        return (
            self.aspect == 1.0
            and self.keystone == (0.0, 0.0)
            and self.tilt == (0.0, 0.0)
            and (self.harmonics.size == 0 or not np.any(self.harmonics))
            and len(self.coeffs) == 5
            and self.radial_base[0] == 0.0
        )

    @property
    def tilt_deg(self) -> float:
        """Angle between the camera axis and the world vertical, degrees."""
        return math.degrees(math.hypot(*self.tilt))

    def radius_angle(self, theta: FloatArray, rho: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Ideal radius r (px) and image angle phi (rad) of table-frame angles."""
        theta = np.asarray(theta, np.float64)
        rho = np.asarray(rho, np.float64)
        r = self.radial(rho)
        phi = self.azimuth_sign * theta + self.azimuth_offset
        h = self.harmonics
        if h.size and np.any(h):
            mid, half = self.rho_norm
            t = (rho - mid) / half
            for k in range(h.shape[0]):
                c, s = np.cos((k + 1) * theta), np.sin((k + 1) * theta)
                pr = np.polynomial.polynomial.polyval(t, h[k, :, 0]) * c
                pr += np.polynomial.polynomial.polyval(t, h[k, :, 1]) * s
                pp = np.polynomial.polynomial.polyval(t, h[k, :, 2]) * c
                pp += np.polynomial.polynomial.polyval(t, h[k, :, 3]) * s
                r = r + pr
                phi = phi + pp
        return np.asarray(r, np.float64), np.asarray(phi, np.float64)

    def pixels(self, theta: FloatArray, rho: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Pixel (u, v) of table-frame angles (theta', rho'), each shaped like the inputs."""
        r, phi = self.radius_angle(theta, rho)
        x, y = r * np.cos(phi), r * np.sin(phi)
        g1, g2 = self.keystone
        if g1 != 0.0 or g2 != 0.0:
            w = 1.0 + g1 * x + g2 * y
            x, y = x / w, y / w
        u0, v0 = self.image_center
        return u0 + x, v0 + self.aspect * y

    def fill_grid(
        self, theta: FloatArray, rho: FloatArray, out: NDArray[np.float32], *, block: int = 64
    ) -> None:
        """Pixels of the grid theta (M,) x rho (N,) into ``out[:N, :M]`` ((>= N, >= M, 2) float32).

        The same numbers as :meth:`pixels` on the meshgrid (to float32), built row
        block by row block from the separable parts: the radial polynomial per
        row, cos/sin of the harmonics per column.
        """
        theta = np.asarray(theta, np.float64)
        rho = np.asarray(rho, np.float64)
        M, N = theta.size, rho.size
        h = self.harmonics if self.harmonics.size and np.any(self.harmonics) else None
        K = 0 if h is None else h.shape[0]
        ck = [np.cos((k + 1) * theta).astype(np.float32) for k in range(K)]
        sk = [np.sin((k + 1) * theta).astype(np.float32) for k in range(K)]
        phi_col = (self.azimuth_sign * theta + self.azimuth_offset).astype(np.float32)
        tangential = h is not None and bool(np.any(h[:, :, 2:]))
        if not tangential:
            cphi, sphi = np.cos(phi_col), np.sin(phi_col)
        r_row = self.radial(rho)
        mid, half = self.rho_norm
        t_row = (rho - mid) / half
        g1, g2 = self.keystone
        u0, v0 = self.image_center
        for j0 in range(0, N, block):
            sl = slice(j0, min(N, j0 + block))
            r = np.broadcast_to(r_row[sl].astype(np.float32)[:, None], (sl.stop - j0, M)).copy()
            phi: NDArray[np.float32] | None = None
            if h is not None:
                tt = t_row[sl]
                if tangential:
                    phi = np.broadcast_to(phi_col, r.shape).copy()
                for k in range(K):
                    coef = [
                        np.polynomial.polynomial.polyval(tt, h[k, :, q]).astype(np.float32)[:, None]
                        for q in range(4)
                    ]
                    r += coef[0] * ck[k] + coef[1] * sk[k]
                    if phi is not None:
                        phi += coef[2] * ck[k] + coef[3] * sk[k]
            if phi is None:
                x, y = r * cphi, r * sphi
            else:
                x, y = r * np.cos(phi), r * np.sin(phi)
            x = np.asarray(x, np.float32)
            y = np.asarray(y, np.float32)
            if g1 != 0.0 or g2 != 0.0:
                w = np.float32(1.0) + np.float32(g1) * x + np.float32(g2) * y
                x, y = np.asarray(x / w, np.float32), np.asarray(y / w, np.float32)
            out[sl, :M, 0] = x + np.float32(u0)
            out[sl, :M, 1] = y * np.float32(self.aspect) + np.float32(v0)

    def ideal_radius(self, u: FloatArray, v: FloatArray) -> FloatArray:
        """Radius (px) of pixels in the ideal frame (aspect and keystone undone)."""
        x = np.asarray(u, np.float64) - self.image_center[0]
        y = (np.asarray(v, np.float64) - self.image_center[1]) / self.aspect
        g1, g2 = self.keystone
        if g1 != 0.0 or g2 != 0.0:  # x' = x / w, w = 1 + g.x  =>  x = x' / (1 - g.x')
            w = 1.0 - g1 * x - g2 * y
            x, y = x / w, y / w
        return np.asarray(np.hypot(x, y), np.float64)

    def project_world(self, dirs: FloatArray) -> FloatArray:
        """(..., 2) pixels of (..., 3) world-frame directions (from O_m)."""
        theta, rho = table_angles(dirs, self.tilt)
        u, v = self.pixels(theta, rho)
        return np.stack([u, v], -1)


# ---------------------------------------------------------------- terms and fitting


@dataclass(frozen=True)
class Terms:
    """Which generalized terms a fit frees (the model order)."""

    center: bool = True
    aspect: bool = False
    tilt: bool = False
    keystone: bool = False
    degree: int = 4  # radial polynomial degree; -1 for none (with ``unified``)
    harmonics: int = 0  # K
    harmonic_degree: int = 0  # D
    unified: bool = False  # the unified model's gamma cos(rho') / (c + sin(rho')) term
    polar: bool = False  # the radial polynomial is 0 at the pole the image center sees
    # with ``polar``: odd powers only of the angle from the pole (a fisheye's r(theta) =
    # k1 theta + k3 theta^3 + k5 theta^5, Kannala-Brandt's form), ``degree`` the highest
    odd: bool = False

    def describe(self) -> str:
        parts = []
        if self.center:
            parts.append("center")
        if self.aspect:
            parts.append("aspect")
        if self.tilt:
            parts.append("tilt")
        if self.keystone:
            parts.append("keystone")
        if self.unified:
            parts.append("unified radial")
        if self.degree >= 0:
            parts.append(
                ("radial odd degree " if self.odd else "radial degree ")
                + str(self.degree)
                + (" through the pole" if self.polar else "")
            )
        if self.harmonics:
            parts.append(f"harmonics 1..{self.harmonics} x elevation degree {self.harmonic_degree}")
        return ", ".join(parts)

    def n_params(self) -> int:
        return (
            (
                (self.degree + 1) // 2
                if self.odd
                else self.degree + 1 - (self.polar and self.degree > 0)
            )
            + 2 * self.unified
            + 1
            + 2 * self.center
            + self.aspect
            + 2 * self.tilt
            + 2 * self.keystone
            + 4 * self.harmonics * (self.harmonic_degree + 1)
        )


ORDERS: tuple[Terms, ...] = (
    # exact for an SVP hyperbolic mirror with two parameters: keeps its shape beyond the
    # landmarks' elevations, where a quartic or sextic from 32 landmarks swung by up to
    # 0.9-2.3 px at 0.1 px noise (docs/results.md)
    Terms(unified=True, degree=-1),
    Terms(),
    Terms(degree=6),  # a hyperbolic mirror's r(rho) is not a quartic: 0.04-0.08 px RMS off
    Terms(aspect=True, tilt=True),
    # after its polynomial twin: kept only when better beyond chance (a fisheye's r is not
    # the unified one, and under 0.3 px noise the simplest-first rule alone could pick it)
    Terms(aspect=True, tilt=True, unified=True, degree=-1),
    Terms(aspect=True, tilt=True, keystone=True),
    # a mirror whose lens sits off its focus: near the unified form, seen in perspective
    # (tuning seeds 900-909, 32 landmarks: panorama up to 0.94 -> 0.60 dB at 0.1 px)
    Terms(aspect=True, tilt=True, keystone=True, unified=True, degree=-1),
    Terms(aspect=True, tilt=True, keystone=True, degree=6),
    Terms(aspect=True, tilt=True, keystone=True, degree=6, harmonics=1, harmonic_degree=1),
    Terms(aspect=True, tilt=True, keystone=True, degree=6, harmonics=2, harmonic_degree=1),
    Terms(aspect=True, tilt=True, keystone=True, degree=6, harmonics=2, harmonic_degree=2),
    Terms(aspect=True, tilt=True, keystone=True, degree=6, harmonics=3, harmonic_degree=2),
    Terms(aspect=True, tilt=True, keystone=True, degree=6, harmonics=4, harmonic_degree=3),
)
"""The nested model orders, simplest first, each radial polynomial free."""


# Each radial polynomial is tried first through r = 0 at the pole the image center sees, then
# free (kept only when better): the table's elevation range reaches past the landmarks', and
# toward a fisheye's zenith a free quartic or sextic from 32 landmarks ended up 1.7-11 dB off
# in the top view; a real mirror's r(rho) (OCamCalib's KaidanOmni) is fitted better free.
# Beside a quartic, odd powers of the angle from the pole come first: a rotationally
# symmetric lens's r(theta) is an odd function of theta (equidistant, equisolid,
# stereographic, Kannala-Brandt), and three odd terms keep that shape past the landmarks
# (tilted fisheye, 32 landmarks, seed 1908: perspective 3.41 -> 1.38 dB).
def _twins(order: Terms) -> tuple[Terms, ...]:
    """``order`` and the radial functions tried with it, fewest parameters first: odd
    powers of the angle from the pole (beside a quartic), the polynomial through the pole,
    then free."""
    if order.degree <= 0:
        return (order,)
    odd = (replace(order, polar=True, odd=True, degree=5),) if order.degree == 4 else ()
    return (*odd, replace(order, polar=True), order)


CANDIDATES: tuple[Terms, ...] = tuple(t for order in ORDERS for t in _twins(order))
"""The nested model orders tried, simplest first."""

POLAR_REACH = 0.5
"""Orders through the pole are tried when it lies within this fraction of the landmarks'
elevation span of them (a fisheye's zenith: 0.1-0.4; OCamCalib's KaidanOmni mirror's nadir:
0.8, where the constraint cost 0.1 px RMS on views left out)."""
MIN_LANDMARKS = 8  # fewer cannot also hold out a fold's landmarks that say anything
KEYSTONE_SCALE = 1e-6  # parameter units of the keystone: 1e-6 / px
RIDGE_PX = 30.0  # a harmonic coefficient of this size costs as much as 1 px of one residual
MAX_LOG_ASPECT = 5.0  # |log aspect| the fit may reach (aspect 0.0067 .. 148; real ones are ~1)


def _poly_in_t_to_rho(c: FloatArray, mid: float, half: float) -> FloatArray:
    """Coefficients in rho of sum c_i t^i with t = (rho - mid) / half."""
    p = np.polynomial.Polynomial(c)(np.polynomial.Polynomial([-mid / half, 1.0 / half]))
    out = np.zeros(len(c))
    out[: len(p.coef)] = p.coef
    return out


def _lm(
    fun: Callable[[FloatArray], FloatArray], p0: FloatArray, *, max_iter: int = 60
) -> FloatArray:
    """Levenberg-Marquardt on residuals ``fun(p)`` (forward-difference Jacobian)."""
    p = np.asarray(p0, np.float64).copy()
    if p.size == 0:
        return p
    r = fun(p)
    cost = float(r @ r)
    lam = 1e-3
    for _ in range(max_iter):
        h = 1e-6 * np.maximum(1.0, np.abs(p))
        J = np.empty((len(r), len(p)))
        for j in range(len(p)):
            q = p.copy()
            q[j] += h[j]
            J[:, j] = (fun(q) - r) / h[j]
        g = J.T @ r
        A = J.T @ J
        d = np.diag(A).copy()
        d[d <= 0] = 1e-12
        rel = 0.0
        improved = False
        for _ in range(10):
            try:
                step = np.linalg.solve(A + lam * np.diag(d), -g)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            q = p + step
            rq = fun(q)
            cq = float(rq @ rq)
            if np.isfinite(cq) and cq < cost:
                rel = (cost - cq) / max(cost, 1e-300)
                p, r, cost = q, rq, cq
                lam = max(lam / 3, 1e-9)
                improved = True
                break
            lam *= 8
        if not improved or rel < 1e-10:
            break
    return p


def _normal_solve(A: FloatArray, b: FloatArray, reg: FloatArray) -> FloatArray:
    """argmin |A x - b|^2 + sum reg x^2 by the (column-scaled) normal equations."""
    norms = np.sqrt(np.sum(A * A, axis=0) + reg)
    norms[norms == 0] = 1.0
    An = A / norms
    G = An.T @ An + np.diag(reg / norms**2)
    try:
        x = np.linalg.solve(G, An.T @ b)
    except np.linalg.LinAlgError:
        x = np.linalg.lstsq(G, An.T @ b, rcond=None)[0]
    return np.asarray(x / norms, np.float64)


@dataclass(frozen=True)
class _Problem:
    """One fit: landmarks, the model order, and the normalization of the elevation."""

    uv: FloatArray
    dirs: FloatArray
    terms: Terms
    s: int
    mid: float
    half: float
    center0: tuple[float, float]
    center_prior: tuple[tuple[float, float], float] | None
    pole: float = -0.5 * math.pi  # rad: the elevation the image center sees (Terms.polar)

    @property
    def polar(self) -> bool:
        return self.terms.polar and self.terms.degree > 0

    def radial_basis(self, rho: FloatArray) -> FloatArray:
        """(n, k) columns of the radial polynomial: t^i, or (rho' - pole) t^i when polar."""
        tt = (rho - self.mid) / self.half
        if not self.polar:
            return np.vander(tt, self.terms.degree + 1, increasing=True)
        if self.terms.odd:
            x = rho - self.pole
            return np.stack([x ** (2 * i + 1) for i in range((self.terms.degree + 1) // 2)], 1)
        return np.vander(tt, self.terms.degree, increasing=True) * (rho - self.pole)[:, None]

    def radial_coeffs(self, sol: FloatArray) -> FloatArray:
        """Coefficients in rho' (rad) of the radial polynomial of :meth:`radial_basis` weights."""
        if sol.size == 0:
            return np.zeros(2)
        if self.polar and self.terms.odd:
            cx = np.zeros(2 * sol.size)
            cx[1::2] = sol
            p = np.polynomial.Polynomial(cx)(np.polynomial.Polynomial([-self.pole, 1.0]))
            return np.asarray(p.coef, np.float64)
        c = _poly_in_t_to_rho(sol, self.mid, self.half)
        if self.polar:
            c = np.asarray(np.polynomial.polynomial.polymul(c, [-self.pole, 1.0]), np.float64)
        if c.size < 2:  # a file holds at least a0, a1
            c = np.concatenate([c, np.zeros(2 - c.size)])
        return np.asarray(c, np.float64)

    def unpack_outer(
        self, q: FloatArray
    ) -> tuple[tuple[float, float], float, tuple[float, float], tuple[float, float]]:
        t, i = self.terms, 0
        center = self.center0
        if t.center:
            center, i = (float(q[0]), float(q[1])), 2
        aspect = 1.0
        if t.aspect:
            # clipped: an optimizer step on wild landmarks must not overflow exp()
            log_aspect = min(max(float(q[i]), -MAX_LOG_ASPECT), MAX_LOG_ASPECT)
            aspect, i = math.exp(log_aspect), i + 1
        tilt = (0.0, 0.0)
        if t.tilt:
            tilt, i = (float(q[i]), float(q[i + 1])), i + 2
        keystone = (0.0, 0.0)
        if t.keystone:
            keystone, i = (float(q[i]) * KEYSTONE_SCALE, float(q[i + 1]) * KEYSTONE_SCALE), i + 2
        return center, aspect, tilt, keystone

    def base_c(self, q: FloatArray) -> float:
        """The unified term's c (the last outer parameter), 0 without one."""
        return float(q[-1]) if self.terms.unified else 0.0

    def pack_outer(self, m: PanoMapping) -> FloatArray:
        t = self.terms
        q: list[float] = []
        if t.center:
            q += list(m.image_center)
        if t.aspect:
            q.append(math.log(m.aspect))
        if t.tilt:
            q += list(m.tilt)
        if t.keystone:
            q += [m.keystone[0] / KEYSTONE_SCALE, m.keystone[1] / KEYSTONE_SCALE]
        if t.unified:
            q.append(m.radial_base[1] if m.radial_base[0] != 0.0 else self.initial_c(m))
        return np.array(q, np.float64)

    def initial_c(self, m: PanoMapping) -> float:
        """The unified term's c that best fits the radii about ``m``'s center (1-D search).

        The pole sin(rho') = -c is kept outside the landmarks' elevations.
        """
        _, rho = table_angles(self.dirs, m.tilt)
        r_obs = m.ideal_radius(self.uv[:, 0], self.uv[:, 1])
        sn = np.sin(rho)
        P = self.radial_basis(rho)
        steps = np.exp(np.linspace(math.log(1e-3), math.log(100.0), 161))
        best, best_c = math.inf, 1.0 + float(np.max(-sn))
        for c in np.concatenate([float(np.max(-sn)) + steps, float(np.min(-sn)) - steps]):
            A = np.concatenate([P, (np.cos(rho) / (c + sn))[:, None]], 1)
            x, *_ = np.linalg.lstsq(A, r_obs, rcond=None)
            cost = float(np.sum((A @ x - r_obs) ** 2))
            if cost < best:
                best, best_c = cost, float(c)
        return best_c

    def solve(
        self, q: FloatArray, want_mapping: bool = False
    ) -> tuple[PanoMapping | None, FloatArray]:
        """The linear part for outer parameters ``q``: the mapping and the residuals (px)."""
        t = self.terms
        center, aspect, tilt, keystone = self.unpack_outer(q)
        theta, rho = table_angles(self.dirs, tilt)
        x = self.uv[:, 0] - center[0]
        y = (self.uv[:, 1] - center[1]) / aspect
        g1, g2 = keystone
        if g1 != 0.0 or g2 != 0.0:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                w = 1.0 - g1 * x - g2 * y  # a wild landmark (1e7 px) may overflow: 1e6 below
                x, y = x / w, y / w
        r_obs = np.hypot(x, y)
        phi_obs = np.arctan2(y, x)
        tt = (rho - self.mid) / self.half
        P = self.radial_basis(rho)
        npoly = P.shape[1]
        c_base = self.base_c(q)
        if t.unified:
            with np.errstate(divide="ignore", invalid="ignore"):
                P = np.concatenate([P, (np.cos(rho) / (c_base + np.sin(rho)))[:, None]], 1)
        H = np.vander(tt, t.harmonic_degree + 1, increasing=True)
        cols = []
        for k in range(1, t.harmonics + 1):
            cols += [H * np.cos(k * theta)[:, None], H * np.sin(k * theta)[:, None]]
        Hk = np.concatenate(cols, 1) if cols else np.zeros((len(tt), 0))
        ridge = 1.0 / RIDGE_PX
        # radius: r_obs = P a + Hk b (harmonics ridge-penalized)
        A = np.concatenate([P, Hk], 1)
        reg = np.zeros(A.shape[1])
        reg[P.shape[1] :] = ridge**2
        sol_r = _normal_solve(A, r_obs, reg)
        # angle: wrap(phi_obs - s theta) = phi0 + Hk c, weighted by the radius (px)
        d = phi_obs - self.s * theta
        c0 = math.atan2(float(np.mean(np.sin(d))), float(np.mean(np.cos(d))))
        d = np.pi - np.mod(np.pi - (d - c0), TWO_PI)
        wts = np.maximum(r_obs, 1.0)
        B = np.concatenate([np.ones((len(tt), 1)), Hk], 1) * wts[:, None]
        reg_a = np.zeros(B.shape[1])
        reg_a[1:] = (ridge * 300.0) ** 2
        sol_a = _normal_solve(B, d * wts, reg_a)
        res = [
            A @ sol_r - r_obs,
            np.sqrt(reg) * sol_r,
            B @ sol_a - d * wts,
            np.sqrt(reg_a) * sol_a,
        ]
        if self.center_prior is not None and t.center:
            (cu, cv), sigma = self.center_prior
            res.append(np.array([(center[0] - cu) / sigma, (center[1] - cv) / sigma]))
        out = np.concatenate(res)
        out = np.where(np.isfinite(out), out, 1e6)
        if not want_mapping:
            return None, out
        harm = np.zeros((t.harmonics, t.harmonic_degree + 1, 4))
        nd = t.harmonic_degree + 1
        for k in range(t.harmonics):
            base = 2 * nd * k
            harm[k, :, 0] = sol_r[P.shape[1] + base : P.shape[1] + base + nd]
            harm[k, :, 1] = sol_r[P.shape[1] + base + nd : P.shape[1] + base + 2 * nd]
            harm[k, :, 2] = sol_a[1 + base : 1 + base + nd]
            harm[k, :, 3] = sol_a[1 + base + nd : 1 + base + 2 * nd]
        m = PanoMapping(
            self.radial_coeffs(sol_r[:npoly]),
            center,
            self.s,
            float(c0 + sol_a[0]),
            aspect,
            keystone,
            tilt,
            harm if t.harmonics else np.zeros((0, 1, 4)),
            (self.mid, self.half),
            (float(sol_r[npoly]), c_base) if t.unified else (0.0, 0.0),
        )
        return m, out


def _fit_one(
    uv: FloatArray,
    dirs: FloatArray,
    terms: Terms,
    start: PanoMapping,
    *,
    mid: float,
    half: float,
    center_prior: tuple[tuple[float, float], float] | None,
    pole: float = -0.5 * math.pi,
) -> PanoMapping:
    """Variable projection: LM over center, aspect, tilt, keystone; the rest by least squares."""
    prob = _Problem(
        uv, dirs, terms, start.azimuth_sign, mid, half, start.image_center, center_prior, pole
    )
    q = _lm(lambda q: prob.solve(q)[1], prob.pack_outer(start))
    m, _ = prob.solve(q, want_mapping=True)
    assert m is not None
    return m


def _initial(uv: FloatArray, dirs: FloatArray, center: tuple[float, float]) -> PanoMapping:
    """The dissertation's fit at ``center`` (Algorithm 1 with the fitted azimuth mapping)."""
    from omnidev.panotable.table import fit_azimuth, fit_radial

    x, y, z = dirs[:, 0], dirs[:, 1], dirs[:, 2]
    theta, rho = np.arctan2(y, x), np.arctan2(z, np.hypot(x, y))
    d = uv - np.asarray(center)
    fit = fit_radial(rho, np.hypot(d[:, 0], d[:, 1]))
    s, phi0, _ = fit_azimuth(theta, np.arctan2(d[:, 1], d[:, 0]))
    return PanoMapping(fit.coeffs, center, s, phi0)


@dataclass(frozen=True)
class CandidateScore:
    """Held-out figures of one model order."""

    terms: Terms
    heldout_rms_px: float
    heldout_p95_px: float
    train_rms_px: float


@dataclass(frozen=True)
class GeneralFit:
    """Result of :func:`fit_general`: the chosen mapping and how it was chosen."""

    mapping: PanoMapping
    terms: Terms
    residual_px: FloatArray  # (n,) distance of each landmark from the model, px
    heldout_px: FloatArray  # (n,) distance of each landmark from the fold's model that left it out
    scores: tuple[CandidateScore, ...]

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.residual_px**2)))

    @property
    def heldout_rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.heldout_px**2)))


def _folds(n: int, groups: IntArray | None, k: int, seed: int) -> list[IntArray]:
    if groups is not None:
        uniq = np.unique(groups)
        if len(uniq) >= 3:
            order = np.random.default_rng(seed).permutation(uniq)
            parts = np.array_split(order, min(k, len(uniq)))
            return [np.flatnonzero(np.isin(groups, part)) for part in parts]
    idx = np.random.default_rng(seed).permutation(n)
    return [np.sort(a) for a in np.array_split(idx, k)]


def fit_general(
    uv: FloatArray,
    dirs: FloatArray,
    image_center: tuple[float, float],
    *,
    candidates: Sequence[Terms] = CANDIDATES,
    groups: IntArray | None = None,
    folds: int = 5,
    tolerance: float = 0.05,
    center_prior_px: float | None = None,
    seed: int = 0,
) -> GeneralFit:
    """Fit the generalized mapping to landmarks; the model order is chosen by held-out residual.

    Args:
        uv: (n, 2) landmark pixels.
        dirs: (n, 3) landmark directions from O_m in the world frame (any length).
        image_center: starting image center (u0, v0) px (detected, or a guess).
        candidates: model orders, simplest first; each is tried only when it has
            at most half as many parameters as there are landmark coordinates, and
            an order through the pole (``Terms.polar``) only when the pole lies
            within :data:`POLAR_REACH` of the landmarks' elevation span of them.
            The harmonics' radial part is not held to 0 at the pole.
        groups: (n,) labels (e.g. the board of each corner); folds then leave out
            whole groups, so a board's corners do not vouch for each other.
        folds: number of cross-validation folds.
        tolerance: the simplest order whose held-out RMS is within this fraction
            of the best one's, or within one standard error of an RMS over the n
            landmarks (1 / sqrt(2 n)) where that is wider, is chosen, unless a
            later order is better on the same held-out landmarks beyond chance (its
            mean squared held-out residual lower by more than :data:`SIGNIFICANCE`
            standard errors of the paired per-landmark difference). A free
            polynomial whose twin through the pole was tried is kept only by the
            second rule. Last, the best twin of the kept order with fewer radial
            parameters (the same terms but the radial function) whose held-out RMS
            is within this fraction of the kept one's replaces it.
        center_prior_px: the 1-sigma uncertainty of ``image_center`` when it was
            measured (a detected center); None lets the landmarks alone decide.

    Raises:
        CalibrationError: fewer landmarks than the simplest order needs.
    """
    uv = np.asarray(uv, np.float64)
    dirs = np.asarray(dirs, np.float64)
    n = len(uv)
    rho = np.arctan2(dirs[:, 2], np.hypot(dirs[:, 0], dirs[:, 1]))
    lo, hi = float(np.min(rho)), float(np.max(rho))
    mid, half = 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-3)
    usable = [c for c in candidates if c.n_params() <= n]  # at most half the 2n equations
    if not usable or n < MIN_LANDMARKS:
        need = max(MIN_LANDMARKS, min(c.n_params() for c in candidates))
        raise CalibrationError(
            f"{n} landmarks are too few for the generalized table (it needs at least {need}); "
            "add landmarks (omnidev landmarks board collects hundreds) or use --model dissertation"
        )
    prior = None if center_prior_px is None else (image_center, float(center_prior_px))
    fold_sets = _folds(n, groups, folds, seed)
    trains = [np.setdiff1d(np.arange(n), test) for test in fold_sets]
    fold_maps: list[PanoMapping | None] = []
    for train in trains:
        try:
            fold_maps.append(_initial(uv[train], dirs[train], image_center))
        except CalibrationError:
            fold_maps.append(None)
    fits: list[PanoMapping] = []
    scores: list[CandidateScore] = []
    helds: list[FloatArray] = []
    m = _initial(uv, dirs, image_center)
    # the image center sees the pole toward which the radius shrinks (a mirror's camera: the
    # nadir; a fisheye looking up: the zenith)
    r_lo, r_hi = m.radial(np.array([lo, hi]))
    pole = 0.5 * math.pi if abs(r_hi) < abs(r_lo) else -0.5 * math.pi
    if abs(pole - (hi if pole > 0 else lo)) > POLAR_REACH * (hi - lo):
        usable = [c for c in usable if not c.polar]  # a pole that far off bends the fit
    worse = 0
    for terms in usable:
        h = np.full(n, np.nan)
        for f, (test, train) in enumerate(zip(fold_sets, trains, strict=True)):
            start = fold_maps[f]
            if start is None or terms.n_params() > len(train):
                continue
            fm = _fit_one(
                uv[train],
                dirs[train],
                terms,
                start,
                mid=mid,
                half=half,
                center_prior=prior,
                pole=pole,
            )
            fold_maps[f] = fm
            h[test] = np.hypot(*(fm.project_world(dirs[test]) - uv[test]).T)
        m = _fit_one(uv, dirs, terms, m, mid=mid, half=half, center_prior=prior, pole=pole)
        fits.append(m)
        h = np.minimum(h, 1e150)  # squares stay finite (a wild landmark's 1e200 px); nan stays
        helds.append(h)
        res = np.minimum(np.hypot(*(m.project_world(dirs) - uv).T), 1e150)
        ok = np.isfinite(h)
        score = CandidateScore(
            terms,
            float(np.sqrt(np.mean(h**2))) if ok.all() else math.inf,
            float(np.percentile(h, 95)) if ok.all() else math.inf,
            float(np.sqrt(np.mean(res**2))),
        )
        best_so_far = min((x.heldout_rms_px for x in scores), default=math.inf)
        scores.append(score)
        if score.heldout_rms_px < best_so_far * (1 - 0.5 * tolerance):
            worse = 0
        elif len(scores) < 2 or _shape(terms) != _shape(scores[-2].terms):
            worse += 1  # a radial function alone says nothing about the terms after it
        if worse >= 2:  # two larger orders in a row bought nothing: stop
            break
    cv = np.array([s.heldout_rms_px for s in scores])
    # a free twin of a polynomial through the pole fits the landmarks' own range better by
    # its extra parameter; it is kept only when better beyond chance, not within the 5 %
    primary = np.array([not (s.terms.degree > 0 and not s.terms.polar) for s in scores])
    if not any(s.terms.polar for s in scores):
        primary[:] = True
    best = float(np.min(np.where(primary, cv, math.inf)))
    if not math.isfinite(best):
        chosen = 0
    else:
        # one standard error of an RMS over n held-out landmarks, 1 / sqrt(2 n), where that
        # is wider than ``tolerance`` (32 landmarks: 12.5 %)
        tol = max(tolerance, 1.0 / math.sqrt(2.0 * n))
        chosen = int(np.flatnonzero(primary & (cv <= best * (1 + tol) + 1e-9))[0])
        for i in range(chosen + 1, len(scores)):
            if math.isfinite(cv[i]) and cv[i] < cv[chosen] and _better(helds[chosen], helds[i]):
                chosen = i
        # a twin of the chosen order with fewer radial parameters (the unified term, odd
        # powers through the pole) within ``tolerance`` of it on the held-out landmarks is
        # kept instead, the best such: its form, not the landmarks' noise, decides how it
        # extrapolates (a non-square-pixel SVP mirror's quartic, chosen within the 5 %
        # under landmark noise, cost up to 3 dB in the panorama; a misaligned mirror's
        # quartic through the pole, 1 % ahead of its unified twin, 3.85 dB against 1.04)
        shape = _shape(scores[chosen].terms)
        twins = [
            i
            for i, sc in enumerate(scores)
            if _shape(sc.terms) == shape
            and sc.terms.n_params() < scores[chosen].terms.n_params()
            and cv[i] <= cv[chosen] * (1 + tolerance)
        ]
        if twins:
            chosen = min(twins, key=lambda i: cv[i])
    mapping = fits[chosen]
    residual = np.hypot(*(mapping.project_world(dirs) - uv).T)
    h = helds[chosen]
    return GeneralFit(
        mapping,
        usable[chosen],
        residual,
        np.where(np.isfinite(h), h, residual),
        tuple(scores),
    )


def _shape(terms: Terms) -> Terms:
    """``terms`` with its radial function set aside (twins differ only there)."""
    return replace(terms, degree=4, unified=False, polar=False, odd=False)


SIGNIFICANCE = 3.0
"""Standard errors by which a larger order's paired held-out gain must exceed chance."""


def _better(base: FloatArray, other: FloatArray) -> bool:
    """True when ``other``'s held-out residuals (px, same landmarks) beat ``base``'s beyond chance.

    The 5 % rule alone keeps a quartic where a degree-6 radial function removes
    a bias smaller than the landmark noise (0.04-0.08 px RMS on a hyperbolic
    mirror under 0.1-0.3 px noise); the paired difference sees it.
    """
    d = base**2 - other**2
    n = d.size
    if n < 8:
        return False
    return bool(np.mean(d) > SIGNIFICANCE * np.std(d, ddof=1) / math.sqrt(n))


def diagnose(
    fit_residual_px: FloatArray,
    heldout_px: FloatArray,
    distances: FloatArray,
    rows: Sequence[int],
    bound_px: float,
    *,
    mapping: PanoMapping | None = None,
    uv: FloatArray | None = None,
    offsets: FloatArray | None = None,
) -> str | None:
    """The likely cause when the held-out residual is over ``bound_px``; None when it is not.

    Args:
        fit_residual_px, heldout_px: (n,) per landmark.
        distances: (n,) landmark distance from the mirror center (landmarks' unit).
        rows: the landmarks' lines in their file (for the message).
        mapping, uv, offsets: the fitted mapping, the (n, 2) pixels and the (n, 3)
            landmark positions relative to the given mirror center; with them a
            shift of the mirror center that would explain the residuals is sought.
    """
    rms = float(np.sqrt(np.mean(heldout_px**2)))
    if rms <= bound_px:
        return None
    if mapping is not None and uv is not None and offsets is not None and len(uv) >= 8:
        shift = _center_shift(mapping, uv, offsets)
        if shift is not None:
            delta, before, after = shift
            return (
                f"no model fits the landmarks: held-out RMS {rms:.2f} px > bound {bound_px:g} px; "
                f"moving the mirror center by ({delta[0]:+.3g}, {delta[1]:+.3g}, {delta[2]:+.3g}) "
                f"(landmarks' unit) would bring the fit RMS from {before:.2f} to {after:.2f} px: "
                "the mirror center (--mirror-center) is probably off"
            )
    med = float(np.median(heldout_px))
    worst = np.argsort(heldout_px)[::-1]
    outliers = [int(i) for i in worst[:5] if heldout_px[i] > max(5 * med, 2 * bound_px)]
    head = f"no model fits the landmarks: held-out RMS {rms:.2f} px > bound {bound_px:g} px; "
    if len(distances) >= 8 and float(np.ptp(distances)) > 0.2 * float(np.median(distances)):
        # Spearman-like: ranks, so that a few very near landmarks do not decide alone
        a = np.argsort(np.argsort(-np.asarray(distances))).astype(float)
        b = np.argsort(np.argsort(heldout_px)).astype(float)
        c = float(np.corrcoef(a, b)[0, 1])
        if c > 0.5:
            return head + (
                f"the residuals grow for near landmarks (rank correlation with nearness {c:.2f}): "
                "the mirror center (--mirror-center) is probably off, or the camera is far "
                "from single-viewpoint"
            )
    if outliers and len(outliers) <= max(1, len(heldout_px) // 10):
        names = ", ".join(f"line {rows[i]} ({heldout_px[i]:.1f} px)" for i in outliers)
        return head + (
            f"landmark(s) {names} lie far from all others' model: mis-clicked or "
            "mis-measured? fix or remove them"
        )
    return head + (
        "the residuals are large everywhere: check that the world coordinates are Z-up in one "
        "unit, that the pixels are of this camera's images (size, no crop or flip), and the "
        "mirror center"
    )


def _center_shift(
    mapping: PanoMapping, uv: FloatArray, offsets: FloatArray
) -> tuple[FloatArray, float, float] | None:
    """A mirror-center shift that explains the residuals, if it does: alternately a
    Gauss-Newton step on the shift and a refit of the mapping (center, aspect, tilt)."""
    delta = np.zeros(3)
    before = float(np.sqrt(np.mean(np.sum((mapping.project_world(offsets) - uv) ** 2, 1))))
    scale = float(np.median(np.linalg.norm(offsets, axis=1)))
    mid, half = mapping.rho_norm
    unified = mapping.radial_base[0] != 0.0
    degree = -1 if unified and not np.any(mapping.coeffs) else len(mapping.coeffs) - 1
    terms = Terms(aspect=True, tilt=True, degree=degree, unified=unified)
    for it in range(6):
        if it:
            mapping = _fit_one(
                uv, offsets - delta, terms, mapping, mid=mid, half=half, center_prior=None
            )
        r = (mapping.project_world(offsets - delta) - uv).ravel()
        J = np.empty((len(r), 3))
        h = 1e-4 * scale
        for k in range(3):
            e = np.zeros(3)
            e[k] = h
            J[:, k] = ((mapping.project_world(offsets - delta - e) - uv).ravel() - r) / h
        step, *_ = np.linalg.lstsq(J, -r, rcond=None)
        delta = delta + step
    after = float(np.sqrt(np.mean(np.sum((mapping.project_world(offsets - delta) - uv) ** 2, 1))))
    if after < 0.5 * before and np.all(np.isfinite(delta)):
        return delta, before, after
    return None


def with_terms(m: PanoMapping, **changes: object) -> PanoMapping:
    """A copy of ``m`` with some attributes changed (for tests and tools)."""
    return replace(m, **changes)  # type: ignore[arg-type]
