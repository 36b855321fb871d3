"""OCamCalib's calibration of the Scaramuzza polynomial model from planar board views.

The model is :class:`omnidev.fisheye.models.Scaramuzza` (OCamCalib's ``ss``, centre, affine
``c d e``), of degree 4 with ``ss[1] = 0`` as OCamCalib fits it. Steps (Scaramuzza,
Martinelli, Siegwart, "A toolbox for easily calibrating omnidirectional cameras", IROS 2006;
docs/fisheye-calibration.md):

1. :func:`linear_extrinsics`: with the image centre known and no affine distortion, each
   corner's sensor point (a, b) = (row - xc, col - yc) and board point (X, Y) give one
   homogeneous linear equation ``a (r21 X + r22 Y + t2) - b (r11 X + r12 Y + t1) = 0`` in
   (r11, r12, r21, r22, t1, t2) (the third component of the cross product of the ray
   ``(a, b, ss(rho))`` with the point ``[r1 r2 t] (X, Y, 1)``); its null vector, the
   orthonormality of r1 and r2 (which gives r31, r32 up to a common sign) and the condition
   that the board lies on the side of the rays it is imaged by fix the rest. The sign of
   (r31, r32) is the sign of the polynomial; OCamCalib's is ``ss[0] < 0``.
2. :func:`linear_polynomial`: the other two cross-product components are linear in the
   polynomial coefficients (shared) and each view's t3: one least-squares solve.
3. :func:`find_centre`: the image centre by a shrinking grid search that minimises the
   reprojection RMS of the linear solution (OCamCalib's ``findcenter``).
4. :func:`refine`: Levenberg-Marquardt on the pixel reprojection error of all corners over
   the intrinsics (``ss``, centre, ``c d e``) and every view's pose together (OCamCalib's
   nonlinear refinement; Urban et al. 2015's bundle adjustment minimises the same error).

Frames: board points in mm (z = 0); poses are returned in the **optical frame** of
:mod:`omnidev.fisheye.models` (``x_opt = R @ X_board + t``), which is OCamCalib's camera frame
with ``(x, y, z)_opt = (y, x, -z)_ocam``. Pixels (u, v) = (column, row), (0, 0) the centre of
the top-left pixel.

The refinement works on the parameter vector of :data:`PARAM_NAMES`: the polynomial is
written ``ss(rho) = a0 (1 + s2 t^2 + s3 t^3 + s4 t^4)`` with ``t = rho / |a0|``, so every
parameter is of order 1 to 1000 whatever the image size (``ss_i = a0 s_i / |a0|^i``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.fisheye.models import Scaramuzza

FloatArray = NDArray[np.float64]

DEGREE = 4
PARAM_NAMES = ("a0", "cx", "cy", "c", "d", "s2", "s3", "s4")
"""Scaramuzza calibration parameters: a0 = ss[0] (px), cx = column and cy = row of the
centre (px, = OCamCalib's yc and xc), the affine matrix ``[[c, d], [d, 1]]`` (OCamCalib's
``[[c, d], [e, 1]]`` with e = d), and the normalised polynomial terms s_i = ss_i |a0|^i / a0.

OCamCalib fits d and e apart, but their antisymmetric part is a rotation of the image about
the centre, which the board poses take up exactly to first order: the data do not determine
it (two runs of the same refinement end at d, e = -0.0087, 0.0050 and -0.0052, 0.0014 with
the same RMS on KaidanOmni). A symmetric matrix fixes that gauge and keeps the two affine
terms the data do determine (pixel aspect and skew)."""

_FLIP = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # ocam <-> optical


class OcamCalibError(ValueError):
    """The linear initialisation or the refinement found no usable solution."""


# ---------------------------------------------------------------- parameters <-> lens


def lens_from_vector(p: Sequence[float] | FloatArray) -> Scaramuzza:
    """The lens of a :data:`PARAM_NAMES` vector (no ``invpol``)."""
    v = [float(x) for x in p]
    a0 = v[0]
    s = abs(a0)
    ss = (a0, 0.0, a0 * v[5] / s**2, a0 * v[6] / s**3, a0 * v[7] / s**4)
    return Scaramuzza(ss, xc=v[2], yc=v[1], c=v[3], d=v[4], e=v[4])


def vector_of(lens: Scaramuzza) -> FloatArray:
    """The :data:`PARAM_NAMES` vector of a degree-4 lens with ss[1] = 0 (d: the mean of d, e)."""
    ss = tuple(lens.ss) + (0.0,) * max(0, DEGREE + 1 - len(lens.ss))
    if len(ss) != DEGREE + 1 or ss[1] != 0.0:
        raise ValueError("the calibration parameters describe degree-4 polynomials with ss[1] = 0")
    a0 = float(ss[0])
    s = abs(a0)
    return np.array(
        [a0, lens.yc, lens.xc, lens.c, 0.5 * (lens.d + lens.e)]
        + [float(ss[i]) * s**i / a0 for i in range(2, DEGREE + 1)],
        np.float64,
    )


# ---------------------------------------------------------------- linear steps


def _sensor(uv: FloatArray, centre: tuple[float, float]) -> tuple[FloatArray, FloatArray]:
    """(a, b) = (row - xc, col - yc) for pixels uv = (col, row) and centre (u, v)."""
    return uv[:, 1] - centre[1], uv[:, 0] - centre[0]


def linear_extrinsics(
    obj: FloatArray, uv: FloatArray, centre: tuple[float, float]
) -> list[FloatArray]:
    """The two candidate ``[r1 r2 t1 t2]`` (OCamCalib frame) of one view, as (3, 3) arrays.

    Column 0 and 1 are r1, r2 (unit, orthogonal), column 2 is (t1, t2, NaN): t3 comes from
    :func:`linear_polynomial`. The two candidates differ in the sign of (r31, r32), which
    is the sign of the polynomial.
    """
    a, b = _sensor(uv, centre)
    x, y = obj[:, 0], obj[:, 1]
    m = np.stack([-b * x, -b * y, a * x, a * y, -b, a], axis=1)
    m = m / np.abs(m).max(axis=0).clip(1e-300)[None, :]
    _, vecs = np.linalg.eigh(np.einsum("ij,ik->jk", m, m))
    scale = np.abs(np.stack([-b * x, -b * y, a * x, a * y, -b, a], axis=1)).max(axis=0)
    h11, h12, h21, h22, t1, t2 = vecs[:, 0] / scale.clip(1e-300)
    b0 = h11 * h12 + h21 * h22
    a0 = (h12 * h12 + h22 * h22) - (h11 * h11 + h21 * h21)
    r31_sq = 0.5 * (a0 + math.sqrt(a0 * a0 + 4.0 * b0 * b0))
    if r31_sq > 1e-12:
        r31 = math.sqrt(r31_sq)
        r32 = -b0 / r31
    else:
        r31, r32 = 0.0, math.sqrt(max(-a0, 0.0))
    lam = 1.0 / math.sqrt(h11 * h11 + h21 * h21 + r31 * r31)
    # the board must lie where its corners look: (a, b) a positive multiple of (A, B)
    big_a = h11 * x + h12 * y + t1
    big_b = h21 * x + h22 * y + t2
    if float(np.sum(a * big_a + b * big_b)) < 0:
        lam = -lam
    out = []
    for sign in (1.0, -1.0):
        r = lam * np.array(
            [[h11, h12, t1], [h21, h22, t2], [sign * r31, sign * r32, math.nan]], np.float64
        )
        out.append(r)
    return out


def linear_polynomial(
    obj: Sequence[FloatArray],
    uv: Sequence[FloatArray],
    extrinsics: Sequence[FloatArray],
    centre: tuple[float, float],
) -> tuple[FloatArray, FloatArray, float]:
    """(ss of degree 4 with ss[1] = 0, t3 per view, RMS of the linear residual).

    Unknowns: a0, a2, a3, a4 (shared) and one t3 per view; equations: the first two
    components of ``(a, b, ss(rho)) x (A, B, C) = 0`` for every corner.
    """
    n_views = len(obj)
    n_poly = DEGREE  # a0, a2 .. a4
    rows, rhs = [], []
    for k, (o, q, ext) in enumerate(zip(obj, uv, extrinsics, strict=True)):
        a, b = _sensor(q, centre)
        rho = np.hypot(a, b)
        x, y = o[:, 0], o[:, 1]
        big_a = ext[0, 0] * x + ext[0, 1] * y + ext[0, 2]
        big_b = ext[1, 0] * x + ext[1, 1] * y + ext[1, 2]
        c0 = ext[2, 0] * x + ext[2, 1] * y  # C without t3
        powers = np.stack([np.ones_like(rho)] + [rho**i for i in range(2, DEGREE + 1)], axis=1)
        t3 = np.zeros((len(rho), n_views))
        # b C - ss B = 0:  -B powers . ss + b t3 = -b c0
        r1 = np.concatenate([-big_b[:, None] * powers, t3], axis=1)
        r1[:, n_poly + k] = b
        # ss A - a C = 0:   A powers . ss - a t3 = a c0
        r2 = np.concatenate([big_a[:, None] * powers, t3.copy()], axis=1)
        r2[:, n_poly + k] = -a
        rows += [r1, r2]
        rhs += [-b * c0, a * c0]
    mat = np.concatenate(rows)
    vec = np.concatenate(rhs)
    scale = np.abs(mat).max(axis=0)
    scale[scale == 0] = 1.0
    ms = mat / scale  # normal equations of the column-scaled system (small: 4 + views)
    # einsum, not BLAS: threaded BLAS on such small matrices costs more than it saves
    sol = np.linalg.solve(np.einsum("ij,ik->jk", ms, ms), np.einsum("ij,i->j", ms, vec)) / scale
    res = np.einsum("ij,j->i", mat, sol) - vec
    ss = np.array([sol[0], 0.0, *sol[1:n_poly]], np.float64)
    return ss, sol[n_poly:], float(np.sqrt(np.mean(res * res)))


def _optical_pose(ext: FloatArray, t3: float) -> tuple[FloatArray, FloatArray]:
    """(rvec, tvec) in the optical frame of an OCamCalib [r1 r2 t] with t3."""
    r1, r2 = ext[:, 0], ext[:, 1]
    r3 = np.cross(r1, r2)
    rot = np.stack([r1, r2, r3], axis=1)
    u, _, vt = np.linalg.svd(rot)
    rot = u @ vt
    t = np.array([ext[0, 2], ext[1, 2], t3])
    rot_opt = _FLIP @ rot
    rvec, _ = cv2.Rodrigues(rot_opt)
    return np.asarray(rvec, np.float64).ravel(), _FLIP @ t


@dataclass(frozen=True)
class LinearSolution:
    """The result of :func:`linear_solution` for one centre."""

    lens: Scaramuzza
    rvecs: list[FloatArray]
    tvecs: list[FloatArray]
    rms_px: float  # reprojection RMS (inf when a corner does not project)


def reprojection(
    lens: Scaramuzza, obj: FloatArray, rvec: FloatArray, tvec: FloatArray
) -> FloatArray:
    """(N, 2) pixels of board points (mm) at an optical-frame pose; NaN where not imaged."""
    rot, _ = cv2.Rodrigues(np.asarray(rvec, np.float64).reshape(3, 1))
    cam = obj @ np.asarray(rot).T + np.asarray(tvec, np.float64).ravel()
    uv, _ = lens.project(cam)
    return np.asarray(uv, np.float64)


def project_views(
    lens: Scaramuzza,
    obj: Sequence[FloatArray],
    rvecs: Sequence[FloatArray],
    tvecs: Sequence[FloatArray],
) -> FloatArray:
    """The pixels of every view's board points, concatenated (one projection call)."""
    cam = []
    for o, r, t in zip(obj, rvecs, tvecs, strict=True):
        rot, _ = cv2.Rodrigues(np.asarray(r, np.float64).reshape(3, 1))
        cam.append(o @ np.asarray(rot).T + np.asarray(t, np.float64).ravel())
    uv, _ = lens.project(np.concatenate(cam))
    return np.asarray(uv, np.float64)


def _rms(err: FloatArray) -> float:
    e = err.reshape(-1, 2)
    if not np.all(np.isfinite(e)):
        return math.inf
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


def linear_solution(
    obj: Sequence[FloatArray], uv: Sequence[FloatArray], centre: tuple[float, float]
) -> LinearSolution:
    """Steps 1 and 2 for a given centre (u, v): the lens (c = 1, d = e = 0) and poses.

    Each view takes the extrinsic candidate whose own polynomial (fitted to it alone) has
    ``ss[0] < 0`` (the other candidate's is the same polynomial negated); then one
    polynomial is fitted to all views. Raises OcamCalibError when the result has
    ``ss[0] >= 0``.
    """
    chosen = []
    for o, q in zip(obj, uv, strict=True):
        first, second = linear_extrinsics(o, q, centre)
        ss, _, _ = linear_polynomial([o], [q], [first], centre)
        chosen.append(first if ss[0] < 0 else second)
    ss, t3, _ = linear_polynomial(obj, uv, chosen, centre)
    if not ss[0] < 0 or not np.all(np.isfinite(ss)):
        raise OcamCalibError(f"the linear polynomial has ss[0] = {ss[0]:.4g} (must be < 0)")
    lens = Scaramuzza(tuple(float(v) for v in ss), xc=centre[1], yc=centre[0])
    rvecs, tvecs = [], []
    for ext, t in zip(chosen, t3, strict=True):
        r, tv = _optical_pose(ext, float(t))
        rvecs.append(r)
        tvecs.append(tv)
    p = np.concatenate(
        [vector_of(lens)] + [np.concatenate([r, t]) for r, t in zip(rvecs, tvecs, strict=True)]
    )
    err = _Reprojector(obj, uv, len(PARAM_NAMES)).residuals(p)
    return LinearSolution(lens, rvecs, tvecs, _rms(err))


def find_centre(
    obj: Sequence[FloatArray],
    uv: Sequence[FloatArray],
    image_size: tuple[int, int],
    *,
    grid: int = 5,
    rounds: int = 4,
    span: float = 0.15,
) -> LinearSolution:
    """The linear solution at the centre that minimises its reprojection RMS.

    A ``grid x grid`` search around the image centre over ``span`` of the image size in each
    direction, then around the best point with a third of the spacing, ``rounds`` times
    (OCamCalib's ``findcenter``). Raises OcamCalibError when no centre gives a solution.
    """
    w, h = image_size
    best: LinearSolution | None = None
    cu, cv = (w - 1) / 2.0, (h - 1) / 2.0
    hu, hv = span * w, span * h
    for _ in range(rounds):
        for du in np.linspace(-hu, hu, grid):
            for dv in np.linspace(-hv, hv, grid):
                try:
                    sol = linear_solution(obj, uv, (cu + float(du), cv + float(dv)))
                except (OcamCalibError, ValueError, np.linalg.LinAlgError):
                    continue
                if best is None or sol.rms_px < best.rms_px:
                    best = sol
        if best is None or not math.isfinite(best.rms_px):
            raise OcamCalibError("no image centre gives a linear solution that images every corner")
        cu, cv = best.lens.yc, best.lens.xc
        hu, hv = 2.0 * hu / max(grid - 1, 1), 2.0 * hv / max(grid - 1, 1)
    assert best is not None
    return best


# ---------------------------------------------------------------- refinement


@dataclass(frozen=True)
class Refined:
    """The result of :func:`refine`."""

    lens: Scaramuzza
    rvecs: list[FloatArray]
    tvecs: list[FloatArray]
    rms_px: float
    iterations: int


class _Reprojector:
    """Pixels of every view's board points for a parameter vector, fast.

    The sensor radius of each corner solves ``r ss(rho) = z rho`` (OCamCalib frame:
    ``r = hypot(x, y)``, ``z`` along the axis): eight Newton steps from the radius of the
    last evaluation (the refinement's steps are small) or, at first, of the observed corner;
    corners where it does not converge to a root in [0, rho_max] go through
    :meth:`Scaramuzza.project` (bracketed, exact).
    """

    def __init__(self, obj: Sequence[FloatArray], uv: Sequence[FloatArray], n_int: int) -> None:
        self.obj = [np.asarray(o, np.float64) for o in obj]
        self.target = np.concatenate(uv).ravel()
        self.n_int = n_int
        self.rho: FloatArray | None = None

    def points(self, p: FloatArray) -> FloatArray:
        poses = p[self.n_int :].reshape(-1, 6)
        cam = []
        for o, pose in zip(self.obj, poses, strict=True):
            rot, _ = cv2.Rodrigues(pose[:3].reshape(3, 1))
            cam.append(o @ np.asarray(rot).T + pose[3:])
        return np.concatenate(cam)

    def residuals(self, p: FloatArray, *, keep: bool = False) -> FloatArray:
        """uv(p) - uv_observed, raveled; NaN where a corner is not imaged. ``keep``: the
        radii found become the next start."""
        try:
            lens = lens_from_vector(p[: self.n_int])
        except ValueError:
            return np.full(self.target.shape, np.nan)
        pts = self.points(p)
        xo, yo, zo = pts[:, 1], pts[:, 0], -pts[:, 2]  # optical -> OCamCalib frame
        r = np.hypot(xo, yo)
        ss = np.asarray(lens.ss, np.float64)
        dss = ss[1:] * np.arange(1, len(ss))
        rho = self.rho
        if rho is None:  # start from the observed corners' radii
            rho = self._radius(lens, self.target.reshape(-1, 2))
        rho = np.nan_to_num(rho.copy(), nan=-ss[0])
        for _ in range(8):
            g = r * np.polynomial.polynomial.polyval(rho, ss) - zo * rho
            dg = r * np.polynomial.polynomial.polyval(rho, dss) - zo
            with np.errstate(divide="ignore", invalid="ignore"):
                rho = rho - g / dg
        g = r * np.polynomial.polynomial.polyval(rho, ss) - zo * rho
        scale = np.abs(zo) + r
        bad = ~(np.isfinite(rho) & (rho >= 0) & (rho <= lens.rho_max))
        bad |= ~(np.abs(g) <= 1e-9 * scale * np.maximum(1.0, np.abs(rho)))
        with np.errstate(invalid="ignore", divide="ignore"):
            a = rho * xo / np.where(r > 0, r, 1.0)  # OCamCalib x (rows)
            b = rho * yo / np.where(r > 0, r, 1.0)
        row = lens.c * a + lens.d * b + lens.xc
        col = lens.e * a + b + lens.yc
        uv = np.stack([col, row], axis=1)
        if bad.any():
            exact, _ = lens.project(pts[bad])
            uv[bad] = exact
            rho[bad] = self._radius(lens, exact)
        if keep:
            self.rho = rho
        return uv.ravel() - self.target

    @staticmethod
    def _radius(lens: Scaramuzza, uv: FloatArray) -> FloatArray:
        dr, dc = uv[:, 1] - lens.xc, uv[:, 0] - lens.yc
        det = lens.c - lens.d * lens.e
        out: FloatArray = np.hypot((dr - lens.d * dc) / det, (lens.c * dc - lens.e * dr) / det)
        return out


def refine(
    lens: Scaramuzza,
    obj: Sequence[FloatArray],
    uv: Sequence[FloatArray],
    rvecs: Sequence[FloatArray],
    tvecs: Sequence[FloatArray],
    *,
    iterations: int = 100,
    fit_affine: bool = True,
) -> Refined:
    """Levenberg-Marquardt on the reprojection error over the intrinsics and all poses.

    ``fit_affine`` False holds c = 1, d = e = 0. The affine matrix is kept symmetric
    (:data:`PARAM_NAMES`). Numerical Jacobian (the intrinsics' columns from one perturbation
    each over all views; the poses' from six perturbations of every pose at once, since a
    view's residuals depend only on its own pose); the damped normal equations are solved
    with the poses eliminated view by view (Schur complement).
    """
    p0 = vector_of(lens)
    n_int = len(p0)
    n_views = len(uv)
    poses = np.concatenate(
        [np.concatenate([np.ravel(r), np.ravel(t)]) for r, t in zip(rvecs, tvecs, strict=True)]
    )
    p = np.concatenate([p0, poses])
    free_int = np.ones(n_int, bool)
    if not fit_affine:
        free_int[3:5] = False
    fi = np.flatnonzero(free_int)
    sizes = [2 * len(q) for q in uv]
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    rep = _Reprojector(obj, uv, n_int)
    res = rep.residuals(p, keep=True)
    if not np.all(np.isfinite(res)):
        raise OcamCalibError("the initial calibration does not image every corner")
    cost = float(res @ res)
    lam = 1e-3
    done = 0
    while done < iterations:
        done += 1
        j_int = np.zeros((len(res), len(fi)))
        for col, k in enumerate(fi):
            hk = 1e-6 * max(1.0, abs(float(p[k])))
            q = p.copy()
            q[k] += hk
            j_int[:, col] = (rep.residuals(q) - res) / hk
        j_pose = np.zeros((len(res), 6))
        dist = np.linalg.norm(p[n_int:].reshape(-1, 6)[:, 3:], axis=1)
        for j in range(6):
            steps = np.full(n_views, 1e-7) if j < 3 else 1e-6 * np.maximum(1.0, dist)
            q = p.copy()
            q[n_int + j :: 6] += steps
            j_pose[:, j] = (rep.residuals(q) - res) / np.repeat(steps, sizes)
        a = np.einsum("ij,ik->jk", j_int, j_int)
        g = np.einsum("ij,i->j", j_int, res)
        blocks = []
        for v in range(n_views):
            sl = slice(starts[v], starts[v + 1])
            jp = j_pose[sl]
            blocks.append(
                (
                    np.einsum("ij,ik->jk", j_int[sl], jp),
                    np.einsum("ij,ik->jk", jp, jp),
                    np.einsum("ij,i->j", jp, res[sl]),
                )
            )
        gain = 0.0
        step_max = 0.0
        for _ in range(12):
            try:
                s_mat = a + lam * np.diag(np.diag(a) + 1e-12)
                rhs = -g.copy()
                solved = []
                for b_v, c_v, g_v in blocks:
                    cd = c_v + lam * np.diag(np.diag(c_v) + 1e-12)
                    cb = np.linalg.solve(cd, np.column_stack([b_v.T, g_v]))
                    s_mat -= b_v @ cb[:, :-1]
                    rhs += b_v @ cb[:, -1]
                    solved.append(cb)
                d_int = np.linalg.solve(s_mat, rhs)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            trial = p.copy()
            trial[fi] += d_int
            for v, cb in enumerate(solved):
                trial[n_int + 6 * v : n_int + 6 * v + 6] += -cb[:, -1] - cb[:, :-1] @ d_int
            step_max = float(np.abs(trial - p).max())
            r2 = rep.residuals(trial)
            c2 = float(r2 @ r2) if np.all(np.isfinite(r2)) else math.inf
            if c2 < cost:
                gain = (cost - c2) / max(cost, 1e-300)
                p, cost, lam = trial, c2, max(lam / 10, 1e-12)
                res = rep.residuals(p, keep=True)
                break
            lam *= 10
        if gain < 1e-12 or step_max < 1e-12:
            break
    out = lens_from_vector(p[:n_int])
    rv = [p[n_int + 6 * v : n_int + 6 * v + 3].copy() for v in range(n_views)]
    tv = [p[n_int + 6 * v + 3 : n_int + 6 * v + 6].copy() for v in range(n_views)]
    final = np.concatenate(
        [reprojection(out, o, r, t) - q for o, q, r, t in zip(obj, uv, rv, tv, strict=True)]
    )
    return Refined(out, rv, tv, _rms(final), done)


# ---------------------------------------------------------------- world2cam polynomial


def fit_invpol(
    lens: Scaramuzza, image_size: tuple[int, int], *, tol_px: float = 0.01, max_degree: int = 20
) -> Scaramuzza:
    """The lens with OCamCalib's ``invpol`` (world2cam) fitted over the image.

    As OCamCalib's ``findinvpoly``: rho as a polynomial in ``t = angle - pi / 2`` over the
    angles from the axis to the farthest image corner (or to where the model's angle stops
    growing), of the lowest degree whose largest error is below ``tol_px``.
    """
    w, h = image_size
    corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [-0.5, h - 0.5], [w - 0.5, h - 0.5]])
    dr, dc = corners[:, 1] - lens.xc, corners[:, 0] - lens.yc
    det = lens.c - lens.d * lens.e
    a = (dr - lens.d * dc) / det
    b = (lens.c * dc - lens.e * dr) / det
    rho_top = min(float(np.hypot(a, b).max()) * 1.02, lens.rho_max)
    rho = np.linspace(0.0, rho_top, 2000)
    alpha = lens.angle(rho)
    t = alpha - math.pi / 2
    best = None
    for deg in range(2, max_degree + 1):
        coef = np.polynomial.polynomial.polyfit(t, rho, deg)
        err = float(np.abs(np.polynomial.polynomial.polyval(t, coef) - rho).max())
        best = coef
        if err < tol_px:
            break
    assert best is not None
    return Scaramuzza(
        lens.ss, lens.xc, lens.yc, lens.c, lens.d, lens.e, tuple(float(c) for c in best)
    )
