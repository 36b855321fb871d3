"""Pano-mapping tables (dissertation ch. 4): learn a camera from landmarks, unwarp with a table.

Frames and units (docs/conventions.md):

- World: the landmarks' frame, Z up, any length unit. The *camera frame* is the
  world frame translated to the mirror center O_m (no rotation): x, y
  horizontal, z up.
- Azimuth theta = atan2(y, x) and elevation rho = atan2(z, hypot(x, y)) of a
  point in the camera frame, radians.
- Image: (u, v) = (column, row) pixels, OpenCV convention (center of the
  top-left pixel is (0, 0)); (u0, v0) is the image center (the image of O_m).
  phi = atan2(v - v0, u - u0) is a pixel's angle and r = hypot(u - u0, v - v0)
  its radius.

The model: r = f_r(rho) = a0 + a1 rho + a2 rho^2 + a3 rho^3 + a4 rho^4 (eq. 4.2)
and phi = s * theta + phi0. The dissertation's azimuth mapping is the identity
(s = +1, phi0 = 0, sec. 4.2.2); omnidev can also fit s (the mirror's handedness)
and phi0 (the camera's rotation about its axis) from the landmarks, so the world
axes need not be aligned with the image axes.

Table entry E_ij (Algorithm 2) holds the *absolute* pixel (u, v) of
theta_i = i 2 pi / M (eq. 4.5) and rho_j = rho_s + j (rho_e - rho_s) / N (eq. 4.6);
the array is stored as (N, M, 2): row j, column i.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.panotable.general import GeneralFit, PanoMapping, diagnose, fit_general, table_angles
from omnidev.views import azimuth_elevation

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

Lookup = Literal["bilinear", "nearest", "analytic"]
LOOKUPS: tuple[Lookup, ...] = ("bilinear", "nearest", "analytic")
AzimuthModel = Literal["fit", "identity"]

DEGREE = 4
MIN_LANDMARKS = DEGREE + 1
MAX_CONDITION = 1e8
TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class LandmarkPolar:
    """Landmarks in polar form: elevation/azimuth in the scene, radius/angle in the image."""

    rho: FloatArray  # elevation, rad
    theta: FloatArray  # azimuth, rad
    r: FloatArray  # image radius from (u0, v0), px
    phi: FloatArray  # image angle atan2(v - v0, u - u0), rad


def landmarks_to_polar(
    uv: FloatArray, xyz_world: FloatArray, mirror_center: FloatArray, image_center: FloatArray
) -> LandmarkPolar:
    """Algorithm 1 steps 1-2: eqs. 4.3-4.4 for every landmark.

    Args:
        uv: (n, 2) landmark pixels.
        xyz_world: (n, 3) landmark world points.
        mirror_center: (3,) world position of O_m.
        image_center: (2,) pixel (u0, v0).
    """
    p = np.asarray(xyz_world, np.float64) - np.asarray(mirror_center, np.float64)
    theta, rho = azimuth_elevation(p)
    d = np.asarray(uv, np.float64) - np.asarray(image_center, np.float64)
    return LandmarkPolar(rho, theta, np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0]))


@dataclass(frozen=True)
class RadialFit:
    """Result of Algorithm 1: the radial stretching function and how well it fits."""

    coeffs: FloatArray  # (5,) a0..a4, r in px for rho in rad
    condition: float  # condition number of the (column-scaled) least-squares system
    residual_px: FloatArray  # (n,) f_r(rho_k) - r_k

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.residual_px**2)))


def radial(coeffs: FloatArray, rho: FloatArray | float) -> FloatArray:
    """Evaluate f_r(rho) = sum a_i rho^i (eq. 4.2); rho in rad, result in px."""
    return np.asarray(np.polynomial.polynomial.polyval(rho, coeffs), np.float64)


def fit_radial(rho: FloatArray, r: FloatArray) -> RadialFit:
    """Algorithm 1 step 3: least-squares fit of the 4th-degree f_r to (rho_k, r_k).

    The system is solved with columns scaled by the largest |rho| for
    conditioning; coefficients are returned for unscaled rho.

    Raises:
        CalibrationError: fewer than 5 landmarks, non-finite values, fewer than 5
            distinct elevations, or an ill-conditioned system.
    """
    rho = np.asarray(rho, np.float64)
    r = np.asarray(r, np.float64)
    n = rho.size
    if n < MIN_LANDMARKS:
        raise CalibrationError(
            f"{n} landmarks: the 4th-degree radial function needs at least {MIN_LANDMARKS}"
        )
    bad = np.flatnonzero(~(np.isfinite(rho) & np.isfinite(r)))
    if bad.size:
        raise CalibrationError(f"landmark {int(bad[0])} has a non-finite elevation or radius")
    distinct = np.unique(np.round(rho, 6)).size
    if distinct < MIN_LANDMARKS:
        raise CalibrationError(
            f"landmarks span only {distinct} distinct elevations; the fit needs "
            f"{MIN_LANDMARKS} (spread landmarks from near the image center to the rim)"
        )
    scale = float(np.max(np.abs(rho))) or 1.0
    A = np.vander(rho / scale, DEGREE + 1, increasing=True)
    norms = np.linalg.norm(A, axis=0)
    An = A / norms
    cond = float(np.linalg.cond(An))
    if not np.isfinite(cond) or cond > MAX_CONDITION:
        raise CalibrationError(
            f"the radial fit is ill-conditioned (condition number {cond:.3g}): the landmarks' "
            "elevations are too close together; add landmarks at other elevations"
        )
    b, *_ = np.linalg.lstsq(An, r, rcond=None)
    coeffs = b / norms / scale ** np.arange(DEGREE + 1)
    return RadialFit(coeffs, cond, radial(coeffs, rho) - r)


def wrap_angle(a: FloatArray | float) -> FloatArray:
    """Angle(s) wrapped to (-pi, pi]."""
    return np.asarray(np.pi - np.mod(np.pi - np.asarray(a, np.float64), TWO_PI))


def fit_azimuth(theta: FloatArray, phi: FloatArray) -> tuple[int, float, FloatArray]:
    """Fit phi = s theta + phi0 (s = +-1) by the circular mean; returns (s, phi0, residual rad)."""
    best: tuple[int, float, FloatArray] | None = None
    for s in (1, -1):
        d = phi - s * theta
        phi0 = float(np.arctan2(np.mean(np.sin(d)), np.mean(np.cos(d))))
        res = wrap_angle(d - phi0)
        if best is None or float(np.sum(res**2)) < float(np.sum(best[2] ** 2)):
            best = (s, phi0, res)
    assert best is not None
    return best


@dataclass(frozen=True)
class PanoTable:
    """A pano-mapping table and the model that filled it.

    Attributes:
        coeffs: a0..aD of f_r (px for rho in rad; D = 4 is eq. 4.2).
        image_center: (u0, v0) px.
        image_size: (width, height) px of the omni-images.
        rho_range: (rho_s, rho_e) rad, the elevations the table covers (table frame).
        M, N: azimuth and elevation divisions (eqs. 4.5-4.6).
        azimuth_sign, azimuth_offset: s and phi0 (rad) of phi = s theta + phi0.
        cutoff_radius: px; pixels nearer the center are the camera's own
            reflection and are not used (0 = none).
        aspect, keystone, tilt, harmonics, rho_norm, radial_base: the generalized terms of
            :class:`omnidev.panotable.general.Mapping` (neutral by default: the
            dissertation's table). With a tilt the table is indexed by the
            camera's own (table-frame) angles and views are turned into it.
    """

    coeffs: FloatArray
    image_center: tuple[float, float]
    image_size: tuple[int, int]
    rho_range: tuple[float, float]
    M: int
    N: int
    azimuth_sign: int = 1
    azimuth_offset: float = 0.0
    cutoff_radius: float = 0.0
    aspect: float = 1.0
    keystone: tuple[float, float] = (0.0, 0.0)
    tilt: tuple[float, float] = (0.0, 0.0)
    harmonics: FloatArray | None = None
    rho_norm: tuple[float, float] = (0.0, 1.0)
    radial_base: tuple[float, float] = (0.0, 0.0)
    _table: NDArray[np.float32] | None = field(default=None, repr=False, compare=False)
    _stored: bool = field(default=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.M < 4 or self.N < 2:
            raise CalibrationError(f"table size {self.M}x{self.N} is too small (M >= 4, N >= 2)")
        if not self.rho_range[1] > self.rho_range[0]:
            raise CalibrationError("elevation range must have rho_e > rho_s")
        if self.azimuth_sign not in (1, -1):
            raise CalibrationError("azimuth_sign must be +1 or -1")
        if not (math.isfinite(self.aspect) and self.aspect > 0):
            raise CalibrationError(f"pixel aspect must be > 0, got {self.aspect}")

    @classmethod
    def from_mapping(
        cls,
        mapping: PanoMapping,
        image_size: tuple[int, int],
        rho_range: tuple[float, float],
        M: int,
        N: int,
        cutoff_radius: float = 0.0,
    ) -> PanoTable:
        """The table of a (generalized) mapping."""
        h = mapping.harmonics
        return cls(
            np.asarray(mapping.coeffs, np.float64),
            mapping.image_center,
            image_size,
            rho_range,
            M,
            N,
            mapping.azimuth_sign,
            mapping.azimuth_offset,
            cutoff_radius,
            mapping.aspect,
            mapping.keystone,
            mapping.tilt,
            None if h.size == 0 else np.asarray(h, np.float64),
            mapping.rho_norm,
            mapping.radial_base,
        )

    @property
    def mapping(self) -> PanoMapping:
        """The function that fills the table (table-frame angles -> pixels)."""
        h = np.zeros((0, 1, 4)) if self.harmonics is None else self.harmonics
        return PanoMapping(
            np.asarray(self.coeffs, np.float64),
            self.image_center,
            self.azimuth_sign,
            self.azimuth_offset,
            self.aspect,
            self.keystone,
            self.tilt,
            h,
            self.rho_norm,
            self.radial_base,
        )

    @property
    def method(self) -> str:
        """``dissertation`` when every generalized term is neutral, else ``general``."""
        return "dissertation" if self.mapping.is_dissertation else "general"

    @property
    def thetas(self) -> FloatArray:
        """theta_i = i 2pi / M (eq. 4.5), rad."""
        return np.arange(self.M, dtype=np.float64) * (TWO_PI / self.M)

    @property
    def rhos(self) -> FloatArray:
        """rho_j = j (rho_e - rho_s) / N + rho_s (eq. 4.6), rad."""
        rs, re = self.rho_range
        return np.arange(self.N, dtype=np.float64) * ((re - rs) / self.N) + rs

    @property
    def table(self) -> NDArray[np.float32]:
        """(N, M, 2) float32 absolute pixels (u, v) of every entry (Algorithm 2, eqs. 4.7-4.8)."""
        return self.padded[: self.N, : self.M]

    @property
    def stored_entries(self) -> bool:
        """True when the entries were given (read from a file), not filled from the mapping."""
        return self._stored

    @property
    def padded(self) -> NDArray[np.float32]:
        """(N + 1, M + 1, 2) float32: the table with column 0 repeated after column M - 1
        (azimuth wraps) and a row N extrapolated linearly from rows N - 2 and N - 1.

        Filled from the mapping on first use (Algorithm 2) and kept."""
        if self._table is None:
            out = np.empty((self.N + 1, self.M + 1, 2), np.float32)
            self.mapping.fill_grid(self.thetas, self.rhos, out)
            _wrap(out)
            object.__setattr__(self, "_table", out)
        assert self._table is not None
        return self._table

    def fill(self) -> NDArray[np.float32]:
        """Algorithm 2: compute every entry from the mapping, (N, M, 2) float32."""
        out = np.empty((self.N, self.M, 2), np.float32)
        self.mapping.fill_grid(self.thetas, self.rhos, out)
        return out

    def with_table(self, table: FloatArray | NDArray[np.float32]) -> PanoTable:
        """The same model holding a given (N, M, 2) table (as read from a file)."""
        if table.shape != (self.N, self.M, 2):
            raise CalibrationError(
                f"table has shape {table.shape}, expected ({self.N}, {self.M}, 2)"
            )
        obj = dataclasses.replace(self, _table=None)
        object.__setattr__(obj, "_table", _pad(np.asarray(table, np.float32)))
        object.__setattr__(obj, "_stored", True)
        return obj

    def lookup(
        self, theta: FloatArray, rho: FloatArray, *, method: Lookup = "bilinear"
    ) -> tuple[FloatArray, BoolArray]:
        """Pixels of table-frame directions (theta, rho) through the table.

        method:
            "nearest": the dissertation's lookup: integer floor of the entry
                indices (eqs. 4.9, 4.12, 4.20, 4.23) and that entry's pixel.
            "bilinear": bilinear interpolation between the four surrounding
                entries (azimuth wraps around; above the last entry row,
                rho_e - step .. rho_e, the last two rows extrapolate linearly).
            "analytic": the mapping evaluated directly, no table (the limit of an
                infinitely fine table).

        Returns (..., 2) float64 pixels and a validity mask (elevation inside the
        table and radius outside the cut-off circle).
        """
        rs, re = self.rho_range
        dr = (re - rs) / self.N
        theta = np.asarray(theta, np.float64)
        rho = np.asarray(rho, np.float64)
        fi = np.mod(theta, TWO_PI) / (TWO_PI / self.M)
        fj = (rho - rs) / dr
        valid = (fj >= 0) & (fj < self.N) & np.isfinite(fj)
        fj = np.where(valid, fj, 0.0)
        if method == "nearest":
            i = np.floor(fi).astype(np.intp) % self.M
            j = np.clip(np.floor(fj).astype(np.intp), 0, self.N - 1)
            uv = self.padded[j, i].astype(np.float64)
        elif method == "bilinear":
            i0f = np.floor(fi)
            a = (fi - i0f)[..., None]
            i0 = i0f.astype(np.intp) % self.M
            j0 = np.clip(np.floor(fj).astype(np.intp), 0, self.N - 1)
            b = (fj - j0)[..., None]
            t = self.padded.reshape(-1, 2)
            k = j0 * (self.M + 1) + i0
            top = (1 - a) * t[k] + a * t[k + 1]
            bottom = (1 - a) * t[k + self.M + 1] + a * t[k + self.M + 2]
            uv = (1 - b) * top + b * bottom
        elif method == "analytic":
            u, v = self.mapping.pixels(theta, rho)
            uv = np.stack([u, v], axis=-1)
        else:
            raise ValueError(f"unknown lookup {method!r}; choose one of {', '.join(LOOKUPS)}")
        if self.cutoff_radius > 0:
            valid &= self._outside_cutoff(uv[..., 0], uv[..., 1])
        return uv, valid

    def _outside_cutoff(
        self, u: FloatArray | NDArray[np.float32], v: FloatArray | NDArray[np.float32]
    ) -> BoolArray:
        if self.method == "dissertation":
            r = np.hypot(u - self.image_center[0], v - self.image_center[1])
        else:
            r = self.mapping.ideal_radius(np.asarray(u, np.float64), np.asarray(v, np.float64))
        return np.asarray(r >= self.cutoff_radius)


def _pad(table: NDArray[np.float32]) -> NDArray[np.float32]:
    """(N, M, 2) -> (N + 1, M + 1, 2): wrap column, extrapolated last row (see PanoTable.padded)."""
    n, m, _ = table.shape
    out = np.empty((n + 1, m + 1, 2), np.float32)
    out[:n, :m] = table
    _wrap(out)
    return out


def _wrap(out: NDArray[np.float32]) -> None:
    """Fill the padding of an (N + 1, M + 1, 2) table whose [:N, :M] part is set."""
    n, m = out.shape[0] - 1, out.shape[1] - 1
    out[:n, m] = out[:n, 0]
    out[n] = 2 * out[n - 1] - out[n - 2]


RadialFn = Callable[[FloatArray], FloatArray]


def _radial_fn(coeffs: FloatArray | RadialFn) -> RadialFn:
    """r(rho) of polynomial coefficients, or the function itself."""
    if callable(coeffs):
        return coeffs
    c = np.asarray(coeffs, np.float64)
    return lambda rho: radial(c, rho)


def default_rho_range(
    coeffs: FloatArray | RadialFn,
    rho_landmarks: FloatArray,
    image_center: tuple[float, float],
    image_size: tuple[int, int],
    *,
    margin: float | None = None,
    r_min: float = 0.0,
    r_max: float | None = None,
) -> tuple[float, float]:
    """Default elevation range of a table.

    The landmarks' elevation span widened by ``margin`` of itself on each side
    (default 0.1, or 0.3 when ``r_max``, the mirror disc's or image circle's
    radius, is known: the range then stops at the disc instead of clipping a
    fisheye's field),
    then narrowed to where f_r stays monotonic and within [r_min, r_max] px
    (default: 0 and the distance from the image center to the farthest image
    corner; the mirror disc's radius when it is known): a 4th-degree
    polynomial is not trusted far outside the data that fixed it. ``coeffs``
    are f_r's polynomial coefficients, or f_r itself (a generalized mapping's
    ``radial``, which may hold the unified term).
    """
    if margin is None:
        margin = 0.1 if r_max is None else 0.3
    lo, hi = float(np.min(rho_landmarks)), float(np.max(rho_landmarks))
    span = hi - lo
    lo, hi = max(lo - margin * span, -math.pi / 2), min(hi + margin * span, math.pi / 2)
    u0, v0 = image_center
    w, h = image_size
    r_lim = math.hypot(max(u0, w - 1 - u0), max(v0, h - 1 - v0)) if r_max is None else r_max
    grid = np.linspace(lo, hi, 2001)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = _radial_fn(coeffs)(grid)
    dr = np.gradient(r, grid)
    mid = int(np.argmin(np.abs(grid - 0.5 * (np.min(rho_landmarks) + np.max(rho_landmarks)))))
    increasing = dr[mid] > 0
    ok = (r >= r_min) & (r <= r_lim) & ((dr > 0) if increasing else (dr < 0))
    a = b = mid
    while a > 0 and ok[a - 1]:
        a -= 1
    while b < grid.size - 1 and ok[b + 1]:
        b += 1
    if not ok[mid] or b - a < 2:
        raise CalibrationError(
            "the fitted radial function is not monotonic over the landmarks' elevations; "
            "check the landmarks, the image center and the mirror center"
        )
    return float(grid[a]), float(grid[b])


def default_table_size(
    coeffs: FloatArray | RadialFn, rho_range: tuple[float, float]
) -> tuple[int, int]:
    """Default (M, N): about one entry per pixel along the outer ring and along the radius.

    M = 2 pi r_max rounded up to a multiple of 8 (at least 360);
    N = |f_r(rho_e) - f_r(rho_s)| + 1 (at least 64).
    """
    grid = np.linspace(rho_range[0], rho_range[1], 512)
    r = _radial_fn(coeffs)(grid)
    r_max = float(np.max(np.abs(r)))
    M = max(360, math.ceil(TWO_PI * r_max / 8.0) * 8)
    N = max(64, math.ceil(abs(float(r[-1] - r[0]))) + 1)
    return M, N


@dataclass(frozen=True)
class Calibration:
    """Everything Algorithm 1 produced, for reporting: the table and per-landmark residuals."""

    table: PanoTable
    fit: RadialFit
    polar: LandmarkPolar
    reprojection_px: FloatArray  # (n,) distance between each landmark's pixel and the model's


def calibrate(
    uv: FloatArray,
    xyz_world: FloatArray,
    mirror_center: FloatArray,
    image_center: tuple[float, float],
    image_size: tuple[int, int],
    *,
    azimuth: AzimuthModel = "fit",
    rho_range: tuple[float, float] | None = None,
    table_size: tuple[int, int] | None = None,
    cutoff_radius: float = 0.0,
    disc_radius: float | None = None,
) -> Calibration:
    """Algorithms 1 and 2: landmarks in, pano-mapping table out.

    Args:
        uv: (n, 2) landmark pixels; xyz_world: (n, 3) their world points.
        mirror_center: world position of O_m; image_center: (u0, v0) px.
        image_size: (width, height) px.
        azimuth: "identity" (the dissertation's phi = theta) or "fit" (s, phi0 from
            the landmarks).
        rho_range: (rho_s, rho_e) rad; default :func:`default_rho_range`.
        table_size: (M, N); default :func:`default_table_size`.
        cutoff_radius: px radius of the self-occluded center (0 = none).
        disc_radius: px radius of the mirror disc when known; the default
            elevation range then stops there.
    """
    uv = np.asarray(uv, np.float64)
    xyz = np.asarray(xyz_world, np.float64)
    if not (np.all(np.isfinite(uv)) and np.all(np.isfinite(xyz))):
        row = int(np.flatnonzero(~(np.isfinite(uv).all(1) & np.isfinite(xyz).all(1)))[0])
        raise CalibrationError(f"landmark {row} has a non-finite value")
    polar = landmarks_to_polar(uv, xyz, np.asarray(mirror_center), np.asarray(image_center))
    fit = fit_radial(polar.rho, polar.r)
    if azimuth == "fit":
        s, phi0, _ = fit_azimuth(polar.theta, polar.phi)
    elif azimuth == "identity":
        s, phi0 = 1, 0.0
    else:
        raise ValueError(f"unknown azimuth model {azimuth!r}")
    rr = rho_range or default_rho_range(
        fit.coeffs, polar.rho, image_center, image_size, r_min=cutoff_radius, r_max=disc_radius
    )
    M, N = table_size or default_table_size(fit.coeffs, rr)
    table = PanoTable(fit.coeffs, image_center, image_size, rr, M, N, s, phi0, cutoff_radius)
    pred, _ = table.lookup(polar.theta, polar.rho, method="analytic")
    reproj = np.hypot(*(pred - uv).T)
    return Calibration(table, fit, polar, reproj)


def dissertation_misfit(calib: Calibration, bound_px: float) -> str:
    """Why the dissertation's table does not fit its landmarks (reprojection RMS over ``bound_px``).

    The radial residuals are regressed on the first two harmonics of the
    azimuth: when they explain most of it, the camera breaks the table's
    symmetry (a tilt, a misaligned lens, non-square pixels or a wrong center).
    """
    rms = float(np.sqrt(np.mean(calib.reprojection_px**2)))
    th = calib.polar.theta
    res = calib.fit.residual_px
    A = np.stack([np.ones_like(th), np.cos(th), np.sin(th), np.cos(2 * th), np.sin(2 * th)], 1)
    explained = 0.0
    if len(th) > 8:
        coef, *_ = np.linalg.lstsq(A, res, rcond=None)
        explained = 1.0 - float(np.var(res - A @ coef)) / max(float(np.var(res)), 1e-12)
    head = (
        f"the dissertation's table does not fit: reprojection RMS {rms:.2f} px > {bound_px:g} px; "
    )
    if explained > 0.5:
        return head + (
            f"the radial residuals vary with azimuth ({explained:.0%} explained by its first two "
            "harmonics): the camera is tilted, its lens is off the mirror axis, its pixels are "
            "not square, or the image center is off; use --model general"
        )
    worst = int(np.argmax(calib.reprojection_px))
    return head + (
        f"the residuals do not follow the azimuth; check the landmarks (the worst is landmark "
        f"{worst}, {calib.reprojection_px[worst]:.1f} px), the mirror center and the units"
    )


@dataclass(frozen=True)
class GeneralCalibration:
    """The generalized table, the fit that chose its terms, and per-landmark residuals."""

    table: PanoTable
    fit: GeneralFit
    reprojection_px: FloatArray  # (n,) px, landmark to the model fitted on all of them
    heldout_px: FloatArray  # (n,) px, landmark to the model of the fold that left it out


def calibrate_general(
    uv: FloatArray,
    xyz_world: FloatArray,
    mirror_center: FloatArray,
    image_center: tuple[float, float],
    image_size: tuple[int, int],
    *,
    rho_range: tuple[float, float] | None = None,
    table_size: tuple[int, int] | None = None,
    cutoff_radius: float = 0.0,
    disc_radius: float | None = None,
    groups: NDArray[np.intp] | None = None,
    center_prior_px: float | None = None,
    max_heldout_px: float | None = None,
    rows: Sequence[int] | None = None,
) -> GeneralCalibration:
    """The generalized pano-mapping table (:mod:`omnidev.panotable.general`) from landmarks.

    Args:
        uv, xyz_world, mirror_center, image_size, rho_range, table_size,
            cutoff_radius, disc_radius: as :func:`calibrate` (elevations and the
            cut-off radius are of the camera's own, table frame).
        image_center: where the fit starts (detected, or a guess); it is fitted.
            ``disc_radius`` and ``cutoff_radius`` are taken as measured about it: the
            range is bounded by the disc's far edge from the fitted center.
        groups: (n,) labels such as the board of each landmark: cross-validation
            then leaves out whole groups.
        center_prior_px: 1-sigma of ``image_center`` when it was measured.
        max_heldout_px: refuse (CalibrationError naming the likely cause) when
            the held-out RMS is larger; None accepts any.
        rows: the landmarks' lines in their file, for the error message.
    """
    uv = np.asarray(uv, np.float64)
    xyz = np.asarray(xyz_world, np.float64)
    if not (np.all(np.isfinite(uv)) and np.all(np.isfinite(xyz))):
        row = int(np.flatnonzero(~(np.isfinite(uv).all(1) & np.isfinite(xyz).all(1)))[0])
        raise CalibrationError(f"landmark {row} has a non-finite value")
    dirs = xyz - np.asarray(mirror_center, np.float64)
    dist = np.linalg.norm(dirs, axis=1)
    if np.any(dist <= 0):
        row = int(np.flatnonzero(dist <= 0)[0])
        raise CalibrationError(f"landmark {row} is at the mirror center")
    fit = fit_general(uv, dirs, image_center, groups=groups, center_prior_px=center_prior_px)
    if max_heldout_px is not None:
        lines = list(rows) if rows is not None else list(range(len(uv)))
        why = diagnose(
            fit.residual_px,
            fit.heldout_px,
            dist,
            lines,
            max_heldout_px,
            mapping=fit.mapping,
            uv=uv,
            offsets=dirs,
        )
        if why is not None:
            raise CalibrationError(why)
    m = fit.mapping
    _, rho = table_angles(dirs, m.tilt)
    w, h = image_size
    u0, v0 = m.image_center
    r_lim = math.hypot(max(u0, w - 1 - u0), max(v0, h - 1 - v0) / m.aspect)
    # the disc and cut-off circle were measured about image_center; from the fitted center
    # (a misaligned lens: a few px off) their far edges lie that much farther
    shift = math.hypot(u0 - image_center[0], v0 - image_center[1])
    rr = rho_range or default_rho_range(
        m.radial,
        rho,
        m.image_center,
        image_size,
        r_min=max(0.0, cutoff_radius - shift),
        r_max=disc_radius + shift if disc_radius is not None else r_lim,
    )
    if rho_range is None:
        near_disc = None if disc_radius is None else max(0.0, disc_radius - shift)
        rr = _reach_inside(m, rho, image_size, rr, cutoff_radius + shift, near_disc)
    M, N = table_size or default_table_size(m.radial, rr)
    table = PanoTable.from_mapping(m, image_size, rr, M, N, cutoff_radius)
    return GeneralCalibration(table, fit, fit.residual_px, fit.heldout_px)


INSIDE_RANGE_MARGIN = 0.5
"""How far past the landmarks' elevation span (a fraction of it) a generalized table
reaches inside the circle the image surely holds (the largest one about the center that
fits in the image, and in the disc when it is measured); elsewhere it stops at 30 %."""


def _reach_inside(
    m: PanoMapping,
    rho: FloatArray,
    image_size: tuple[int, int],
    rr: tuple[float, float],
    r_min: float,
    near_disc: float | None,
) -> tuple[float, float]:
    """``rr`` widened to :data:`INSIDE_RANGE_MARGIN` of the landmarks' span where the radius
    (px, about the fitted center) stays above ``r_min`` and inside the image's inscribed
    circle and ``near_disc`` (the measured disc's near edge; None when not measured).

    32 landmarks of a tilted fisheye 21-83 degrees up (table frame) left 3-8 % of its
    panorama and perspective view below a 30 % range: 27 and 32 dB below the exact maps
    (docs/results.md, seed 1305). A 50 % range everywhere reached 45 degrees past a
    fisheye's field when no disc bounds it; inside the inscribed circle it cannot.
    """
    w, h = image_size
    u0, v0 = m.image_center
    r_in = min(u0, w - 1 - u0, v0 / m.aspect, (h - 1 - v0) / m.aspect)
    if near_disc is not None:
        r_in = min(r_in, near_disc)
    try:
        lo, hi = default_rho_range(
            m.radial,
            rho,
            m.image_center,
            image_size,
            margin=INSIDE_RANGE_MARGIN,
            r_min=r_min,
            r_max=r_in,
        )
    except CalibrationError:  # the landmarks themselves reach past the inscribed circle
        return rr
    return (min(rr[0], lo), max(rr[1], hi))


def dissertation_plane_angles(
    k: FloatArray, l: FloatArray, MQ: int, NQ: int, D: float, W: float, H: float
) -> tuple[FloatArray, FloatArray]:
    """Azimuth (from the line O_m P_r) and elevation of pixel (k, l) by eqs. 4.13-4.19, 4.21-4.22.

    Kept to show that :class:`omnidev.views.PlaneView.from_dissertation` is the
    same geometry. Eq. 4.18 reads ``h = l sin(beta)``; the figure and eq. 4.19
    make clear that the horizontal distance ell is meant.
    """
    phi = np.arccos(1 - W**2 / (2 * D**2))  # eq. 4.14
    beta = (np.pi - phi) / 2  # eq. 4.15
    ell = np.asarray(k, np.float64) * W / MQ  # eq. 4.16
    L = np.sqrt(D**2 + ell**2 - 2 * ell * D * np.cos(beta))  # eq. 4.17
    theta = np.arcsin(ell * np.sin(beta) / L)  # eqs. 4.18-4.19
    Hq = np.asarray(l, np.float64) * H / NQ  # eq. 4.21
    rho = np.arctan(Hq / L)  # eq. 4.22
    return theta, rho
