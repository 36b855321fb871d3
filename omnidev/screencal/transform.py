"""Image -> screen transforms fitted to the landmark grid (sec. 5.2.3 and better ones).

Every transform maps (N, 2) image pixels ``(u, v)`` to (N, 2) screen pixels
``(x, y)`` (both: top-left pixel centre at (0, 0)) and returns NaN where it is not
defined. Methods:

- ``idw``: the dissertation's inverse-distance-weighted interpolation in each cell of
  the (N+2) x (N+2) grid (eqs. 5.4-5.5), and in the border area in cells extended to
  the image border (Fig. 5.12).
- ``bilinear``: the same cells, inverse-bilinear interpolation (exact for a cell that
  is the perspective image of a rectangle seen straight on, and continuous across
  cell sides, which IDW is not).
- ``homography``: one global homography (cv2.findHomography, least squares) fitted to
  the dots.
- ``radial``: a lens model fitted to all dots by least squares - undistortion
  ``p_u = c + (p - c)(1 + k1 r^2 + k2 r^4 + k3 r^6)`` (r normalised by the image
  half-diagonal, centre c free), or the lens's forward distortion of that form inverted
  (:data:`LENS_FORMS`; both fitted and the smaller residual kept by default), followed
  by a homography, the screen's edges held
  beyond the outer dots - plus a correction interpolated bilinearly from its
  residuals at the dots (screen lattice) where those residuals form a smooth field
  rather than detection noise.
- ``tsai`` lives in :mod:`omnidev.screencal.tsai`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import partial
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.screencal.grid import LandmarkGrid
from omnidev.screencal.lsq import levenberg_marquardt

FloatArray = NDArray[np.float64]
Params = dict[str, FloatArray]


class ImageToScreen(Protocol):
    """A fitted image -> screen map."""

    name: str

    def __call__(self, uv: FloatArray) -> FloatArray: ...

    def params(self) -> Params: ...


def _as_points(uv: FloatArray) -> FloatArray:
    pts = np.asarray(uv, np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must be (N, 2), got shape {pts.shape}")
    return pts


# ---------------------------------------------------------------- cells (idw, bilinear)


def _extend(
    a: FloatArray, b: FloatArray, sa: FloatArray, sb: FloatArray, axis: int, c: float
) -> tuple[FloatArray, FloatArray]:
    """Continue the line a -> b (image) to the image border line (coordinate ``axis``
    = c); screen coordinates extrapolated linearly along it (Fig. 5.12)."""
    d = b[..., axis] - a[..., axis]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(np.abs(d) > 1e-9, (c - b[..., axis]) / d, 0.0)
    t = np.maximum(t, 0.0)[..., None]
    return b + t * (b - a), sb + t * (sb - sa)


def grid_cells(grid: LandmarkGrid, image_size: tuple[int, int]) -> tuple[FloatArray, FloatArray]:
    """The basic regions as quads: image (Q, 4, 2) and screen (Q, 4, 2), corners in the
    order top-left, top-right, bottom-right, bottom-left. First the (N+1)^2 cells of
    the display area, then the cells of the border area: each outer cell side
    extended to the image border (u = -0.5, W - 0.5; v = -0.5, H - 0.5)."""
    gi, gs = grid.image, grid.screen
    w, h = image_size
    img = [np.stack([gi[:-1, :-1], gi[:-1, 1:], gi[1:, 1:], gi[1:, :-1]], axis=2).reshape(-1, 4, 2)]
    scr = [np.stack([gs[:-1, :-1], gs[:-1, 1:], gs[1:, 1:], gs[1:, :-1]], axis=2).reshape(-1, 4, 2)]
    # top: lines from row 1 through row 0 to v = -0.5
    ti, ts = _extend(gi[1], gi[0], gs[1], gs[0], 1, -0.5)
    img.append(np.stack([ti[:-1], ti[1:], gi[0, 1:], gi[0, :-1]], axis=1))
    scr.append(np.stack([ts[:-1], ts[1:], gs[0, 1:], gs[0, :-1]], axis=1))
    bi, bs = _extend(gi[-2], gi[-1], gs[-2], gs[-1], 1, h - 0.5)
    img.append(np.stack([gi[-1, :-1], gi[-1, 1:], bi[1:], bi[:-1]], axis=1))
    scr.append(np.stack([gs[-1, :-1], gs[-1, 1:], bs[1:], bs[:-1]], axis=1))
    li, ls = _extend(gi[:, 1], gi[:, 0], gs[:, 1], gs[:, 0], 0, -0.5)
    img.append(np.stack([li[:-1], gi[:-1, 0], gi[1:, 0], li[1:]], axis=1))
    scr.append(np.stack([ls[:-1], gs[:-1, 0], gs[1:, 0], ls[1:]], axis=1))
    ri, rs = _extend(gi[:, -2], gi[:, -1], gs[:, -2], gs[:, -1], 0, w - 0.5)
    img.append(np.stack([gi[:-1, -1], ri[:-1], ri[1:], gi[1:, -1]], axis=1))
    scr.append(np.stack([gs[:-1, -1], rs[:-1], rs[1:], gs[1:, -1]], axis=1))
    return np.concatenate(img), np.concatenate(scr)


def inverse_bilinear(quads: FloatArray, pts: FloatArray, iterations: int = 8) -> FloatArray:
    """(s, t) of each point in each quad, (M, Q, 2): p = (1-s)(1-t) q0 + s(1-t) q1 +
    s t q2 + (1-s) t q3, by Newton's method from the quad centre."""
    q0, q1, q2, q3 = (quads[None, :, k] for k in range(4))
    p = pts[:, None, :]
    st = np.full((len(pts), len(quads), 2), 0.5)
    for _ in range(iterations):
        s, t = st[..., :1], st[..., 1:]
        f = (1 - s) * (1 - t) * q0 + s * (1 - t) * q1 + s * t * q2 + (1 - s) * t * q3 - p
        ds = (1 - t) * (q1 - q0) + t * (q2 - q3)
        dt = (1 - s) * (q3 - q0) + s * (q2 - q1)
        det = ds[..., 0] * dt[..., 1] - ds[..., 1] * dt[..., 0]
        det = np.where(np.abs(det) < 1e-12, np.nan, det)
        st[..., 0] -= (f[..., 0] * dt[..., 1] - f[..., 1] * dt[..., 0]) / det
        st[..., 1] -= (ds[..., 0] * f[..., 1] - ds[..., 1] * f[..., 0]) / det
    return st


def inverse_bilinear_pairs(quads: FloatArray, pts: FloatArray, iterations: int = 8) -> FloatArray:
    """(s, t) of point k in quad k, (K, 2): :func:`inverse_bilinear` for given pairs."""
    if len(pts) == 0:
        return np.zeros((0, 2))
    q0, q1, q2, q3 = (quads[:, k] for k in range(4))
    out = np.full((len(pts), 2), 0.5)
    with np.errstate(invalid="ignore", divide="ignore"):
        for _ in range(iterations):
            s, t = out[:, :1], out[:, 1:]
            f = (1 - s) * (1 - t) * q0 + s * (1 - t) * q1 + s * t * q2 + (1 - s) * t * q3 - pts
            ds = (1 - t) * (q1 - q0) + t * (q2 - q3)
            dt = (1 - s) * (q3 - q0) + s * (q2 - q1)
            det = ds[:, 0] * dt[:, 1] - ds[:, 1] * dt[:, 0]
            det = np.where(np.abs(det) < 1e-12, np.nan, det)
            out[:, 0] -= (f[:, 0] * dt[:, 1] - f[:, 1] * dt[:, 0]) / det
            out[:, 1] -= (ds[:, 0] * f[:, 1] - ds[:, 1] * f[:, 0]) / det
    return out


class CellMap:
    """Interpolation in the basic regions of the landmark grid (``idw`` or ``bilinear``)."""

    def __init__(self, grid: LandmarkGrid, image_size: tuple[int, int], *, kind: str) -> None:
        if kind not in ("idw", "bilinear"):
            raise ValueError(f"cell interpolation {kind!r}: 'idw' or 'bilinear'")
        self.name = kind
        self.grid = grid
        self.image_size = image_size
        self.quads_image, self.quads_screen = grid_cells(grid, image_size)

    def params(self) -> Params:
        r2, c2 = self.grid.image.shape[:2]
        return {
            "grid_image": self.grid.image.reshape(r2 * c2, 2),
            "grid_screen": self.grid.screen.reshape(r2 * c2, 2),
            "grid_shape": np.array([r2, c2], np.float64),
        }

    def __call__(self, uv: FloatArray) -> FloatArray:
        pts = _as_points(uv)
        out = np.full(pts.shape, np.nan)
        eps = 1e-6
        qi = self.quads_image
        lo_b, hi_b = qi.min(axis=1) - 1e-6, qi.max(axis=1) + 1e-6  # a cell lies in its corners' box
        for lo in range(0, len(pts), 4096):
            chunk = pts[lo : lo + 4096]
            inbox = (
                (chunk[:, None, 0] >= lo_b[None, :, 0])
                & (chunk[:, None, 0] <= hi_b[None, :, 0])
                & (chunk[:, None, 1] >= lo_b[None, :, 1])
                & (chunk[:, None, 1] <= hi_b[None, :, 1])
            )
            pi, cq = np.nonzero(inbox)  # candidate (point, cell) pairs, cells ascending
            st = inverse_bilinear_pairs(qi[cq], chunk[pi])
            ok = np.all((st >= -eps) & (st <= 1 + eps), axis=1) & np.isfinite(st).all(axis=1)
            pi, cq, st = pi[ok], cq[ok], st[ok]
            first = np.r_[True, pi[1:] != pi[:-1]]  # the lowest-numbered cell holding it
            pi, cq, st = pi[first], cq[first], st[first]
            p = chunk[pi]
            corners_s = self.quads_screen[cq]
            if self.name == "bilinear":
                s_, t_ = st[:, :1], st[:, 1:]
                res = (
                    (1 - s_) * (1 - t_) * corners_s[:, 0]
                    + s_ * (1 - t_) * corners_s[:, 1]
                    + s_ * t_ * corners_s[:, 2]
                    + (1 - s_) * t_ * corners_s[:, 3]
                )
            else:  # eqs. 5.4-5.5: w_k = 1 / d_k
                d = np.hypot(*(qi[cq] - p[:, None, :]).transpose(2, 0, 1))
                wgt = 1.0 / np.maximum(d, 1e-9)
                res = (wgt[..., None] * corners_s).sum(axis=1) / wgt.sum(axis=1)[:, None]
            block = out[lo : lo + 4096]
            block[pi] = res
        return out


# ---------------------------------------------------------------- global homography


class HomographyMap:
    """One homography image -> screen (cv2.findHomography, all points, least squares)."""

    name = "homography"

    def __init__(self, hmat: FloatArray) -> None:
        self.hmat = np.asarray(hmat, np.float64).reshape(3, 3)

    @classmethod
    def fit(cls, uv: FloatArray, xy: FloatArray) -> HomographyMap:
        hmat, _ = cv2.findHomography(uv.astype(np.float64), xy.astype(np.float64), 0)
        return cls(np.asarray(hmat, np.float64))

    def params(self) -> Params:
        return {"H": self.hmat}

    def __call__(self, uv: FloatArray) -> FloatArray:
        pts = _as_points(uv)
        q = np.c_[pts, np.ones(len(pts))] @ self.hmat.T
        return np.asarray(q[:, :2] / q[:, 2:], np.float64)


# ---------------------------------------------------------------- radial + homography + residual


DOT_NOISE_PX = 0.07  # image px: the dot centres' typical error on the tuning scenes
CORRECTION_GAIN = 0.5  # "auto": the neighbours must predict half the residuals' power


def residual_predictability(field: FloatArray, found: NDArray[np.bool_]) -> float:
    """How well each found dot's residual (``field``, (rows, cols, 2)) is predicted by
    the mean of its found 4-neighbours (at least two): the squared prediction error
    over the squared residuals, summed over the dots. About 1.25 for independent
    noise, near 0 for a smooth field; inf when no dot has two found neighbours."""
    rows, cols = int(field.shape[0]), int(field.shape[1])
    f = np.asarray(found, np.bool_).reshape(rows, cols)
    pad = np.zeros((rows + 2, cols + 2), np.float64)
    pad[1:-1, 1:-1] = f
    vals = np.zeros((rows + 2, cols + 2, 2))
    vals[1:-1, 1:-1] = np.where(f[..., None], field, 0.0)
    count = np.zeros((rows, cols))
    total = np.zeros((rows, cols, 2))
    for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        count += pad[1 + di : rows + 1 + di, 1 + dj : cols + 1 + dj]
        total += vals[1 + di : rows + 1 + di, 1 + dj : cols + 1 + dj]
    use = f & (count >= 2)
    if not use.any():
        return math.inf
    pred = total[use] / count[use][:, None]
    err = float(np.sum((field[use] - pred) ** 2))
    return err / max(float(np.sum(field[use] ** 2)), 1e-300)


LENS_FORMS = ("poly", "brown")
"""How the radial model undoes the lens: ``poly``, a polynomial in the distorted radius
(``p_u = c + (p - c)(1 + k1 r^2 + k2 r^4 + k3 r^6)``); ``brown``, the lens's forward
distortion ``r_d = r_u (1 + k1 r_u^2 + k2 r_u^4 + k3 r_u^6)`` (Brown-Conrady, OpenCV's
radial terms) inverted by Newton's method."""
_NEWTON_STEPS = 12


def _undistort_brown(r_d: FloatArray, k1: float, k2: float, k3: float) -> FloatArray:
    """``r_u`` with ``r_u (1 + k1 r_u^2 + k2 r_u^4 + k3 r_u^6) = r_d`` (normalised radii),
    by Newton's method from ``r_d / (1 + k1 r_d^2 + ...)``, kept within ``r_d / 4 .. 4
    r_d`` (a lens moves a point by less than that); where the forward map turns back (a
    barrel lens beyond its widest point) the step is held, so the result stays finite
    for any k."""
    lo, hi = 0.25 * r_d, 4.0 * r_d
    r2 = r_d * r_d
    r = np.clip(r_d / np.maximum(1 + r2 * (k1 + r2 * (k2 + r2 * k3)), 0.1), lo, hi)
    for _ in range(_NEWTON_STEPS):
        r2 = r * r
        f = r * (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) - r_d
        if not np.any(np.abs(f) > 1e-13):
            break
        df = 1 + r2 * (3 * k1 + r2 * (5 * k2 + r2 * 7 * k3))
        r = np.clip(r - f / np.maximum(df, 0.1), lo, hi)
    return r


def _radial_apply(p: FloatArray, pts: FloatArray, scale: float, form: str = "poly") -> FloatArray:
    """Image px -> screen px of the radial model with parameter vector ``p``:
    [cx, cy, k1, k2, k3, h11, h12, h13, h21, h22, h23, h31, h32] (h33 = 1); ``form``
    (:data:`LENS_FORMS`): what k1-k3 describe."""
    x = (pts[:, 0] - p[0]) / scale
    y = (pts[:, 1] - p[1]) / scale
    r2 = x * x + y * y
    if form == "brown":
        r_d = np.sqrt(r2)
        f = _undistort_brown(r_d, p[2], p[3], p[4]) / np.maximum(r_d, 1e-12)
    else:
        f = 1 + r2 * (p[2] + r2 * (p[3] + r2 * p[4]))
    x, y = x * f, y * f
    den = p[11] * x + p[12] * y + 1.0
    out = np.empty((len(pts), 2))
    out[:, 0] = (p[5] * x + p[6] * y + p[7]) / den
    out[:, 1] = (p[8] * x + p[9] * y + p[10]) / den
    return out


class RadialMap:
    """Radial undistortion + homography fitted to the dots, plus the bilinear
    interpolation of its residuals over the dots' screen lattice."""

    name = "radial"

    def __init__(
        self,
        p: FloatArray,
        scale: float,
        residual: FloatArray,
        lattice: FloatArray,
        form: str = "poly",
    ) -> None:
        if form not in LENS_FORMS:
            raise ValueError(f"lens form {form!r}: one of {', '.join(LENS_FORMS)}")
        self.form = form
        self.p = np.asarray(p, np.float64)
        self.scale = float(scale)
        self.residual = np.asarray(residual, np.float64)  # (rows, cols, 2) screen px
        self.lattice = np.asarray(lattice, np.float64)  # x0, y0, sx, sy of the dot lattice

    @classmethod
    def fit(
        cls,
        uv: FloatArray,
        xy: FloatArray,
        image_size: tuple[int, int],
        lattice: FloatArray,
        n: int | tuple[int, int],
        found: NDArray[np.bool_],
        *,
        correct: bool | str = "auto",
        edges: Sequence[tuple[FloatArray, int, float]] | None = None,
        edge_weight: float = 0.2,
        edge_offset: str = "side",
        edge_tie: float = 0.15,
        edge_scatter: bool = True,
        terms: int | None = None,
        form: str = "poly",
    ) -> RadialMap:
        """Fit to the found dots ``uv`` (M, 2 image px) with screen ``xy`` (M, 2); ``n``:
        the lattice's dots per side, or (rows, cols); ``found`` (rows*cols,).

        ``edges``: points on the screen's edges, (K, 4) arrays of image px and outward
        normal, each set with the screen coordinate (0: x, 1: y) and value it must map
        to (e.g. the top edge: y = -0.5); each point weighs ``edge_weight`` of a dot
        coordinate. They hold the model where it extrapolates beyond the outer dots.
        An offset along the normals is fitted with them, one per set
        (``edge_offset="side"``, default) or one for all (``"common"``): where an
        edge appears to be depends on blur, bloom, the camera's tone curve and the
        light on that side, its shape does not. On the tuning scenes of issue 12
        the measured edges sat 0.1-0.3 image px off the truth, differently on each
        side. ``edge_tie`` (image px; 0: free): the sides' offsets are tied to their
        mean as if each difference were measured to within ``edge_tie``, weighed like
        a dot coordinate measured to within ``DOT_NOISE_PX``. ``edge_scatter``: after
        the fit, each side's weight is lowered to the dots' mean squared residual
        over that side's (inverse-variance weights; never above ``edge_weight``) and
        the fit repeated: a codec's blocks can scatter a side's points by 0.3-0.6
        image px (h264 at 640x480 on issue 12's scenes), and a side that noisy
        bent the model near the corners by more than the dots allow.

        ``correct``: add the bilinear interpolation of the dot residuals (True), not
        (False), or ``"auto"`` (default): only when the residuals are a field the
        neighbours predict, i.e. each dot's residual predicted from its found
        4-neighbours' leaves less than ``CORRECTION_GAIN`` of its power
        (:func:`residual_predictability`). Residuals that are detection noise are
        not predictable and are left out: interpolating them passes the noise on."""
        rows, cols = (n, n) if isinstance(n, int) else (int(n[0]), int(n[1]))
        w, h = image_size
        scale = 0.5 * float(np.hypot(w, h))
        c0 = np.array([(w - 1) / 2, (h - 1) / 2])
        hmat, _ = cv2.findHomography((uv - c0) / scale, xy, 0)
        hmat = np.asarray(hmat, np.float64) / hmat[2, 2]
        p0 = np.concatenate([c0, [0.0, 0.0, 0.0], hmat.ravel()[:8]])
        sx = float(np.ptp(xy[:, 0])) or 1.0

        edge_sets = [
            (np.asarray(e, np.float64).reshape(-1, 4), a, v) for e, a, v in edges or () if len(e)
        ]
        if edge_offset not in ("side", "common"):
            raise ValueError(f"edge_offset {edge_offset!r}: 'side' or 'common'")
        if correct not in (True, False, "auto"):
            raise ValueError(f"correct {correct!r}: True, False or 'auto'")
        weights = np.full(len(edge_sets), math.sqrt(edge_weight))
        n_off = len(edge_sets) if edge_offset == "side" else min(len(edge_sets), 1)
        # a dot coordinate's noise (DOT_NOISE_PX image px) in screen px: the tie weighs
        # like a measurement of that quality
        tie_unit = DOT_NOISE_PX * sx / max(float(np.ptp(uv[:, 0])), 1e-9)

        if terms is None:
            terms = 3 if found.all() else 2  # a partial grid: fewer terms extrapolate better
        if terms not in (1, 2, 3):
            raise ValueError(f"terms {terms!r}: 1, 2 or 3")
        if form not in (*LENS_FORMS, "auto"):
            raise ValueError(f"form {form!r}: one of {', '.join(LENS_FORMS)} or 'auto'")

        def resid(p: FloatArray, k: int, lens: str, wts: FloatArray) -> FloatArray:
            pp = p[:13].copy()
            pp[2 + k : 5] = 0.0
            parts = [(_radial_apply(pp, uv, scale, lens) - xy).ravel()]
            for i, (e, axis, value) in enumerate(edge_sets):  # edge points land on their edge
                delta = p[13 + min(i, n_off - 1)]  # shifted along the normal (image px)
                pts = e[:, :2] + delta * e[:, 2:]
                parts.append(wts[i] * (_radial_apply(pp, pts, scale, lens)[:, axis] - value))
            if n_off > 1 and edge_tie > 0:  # the sides' offsets differ by ~edge_tie
                d = p[13 : 13 + n_off]
                parts.append((d - d.mean()) * (tie_unit / edge_tie))
            return np.concatenate(parts) / sx

        def solve(lens: str) -> tuple[FloatArray, float]:
            """The parameters under lens form ``lens`` and their cost at the first
            weights (comparable across forms)."""
            wts = weights.copy()
            p = np.append(p0, np.zeros(n_off))  # then the edges' offsets along their normals
            for k in range(1, terms + 1):  # grow the radial series: stabler than all at once
                p = levenberg_marquardt(partial(resid, k=k, lens=lens, wts=wts), p)
                p[2 + k : 5] = 0.0
            if edge_scatter and edge_sets:  # a side scattering more than the dots weighs less
                r = resid(p, terms, lens, wts) * sx
                at = 2 * len(uv)
                dot_power = float(np.mean(r[:at] ** 2))
                for i, (e, _, _) in enumerate(edge_sets):
                    side_power = float(np.mean((r[at : at + len(e)] / wts[i]) ** 2))
                    at += len(e)
                    wts[i] = math.sqrt(min(edge_weight, dot_power / max(side_power, 1e-300)))
                p = levenberg_marquardt(partial(resid, k=terms, lens=lens, wts=wts), p)
            r = resid(p, terms, lens, weights)
            return p, float(r @ r)

        fits = {lens: solve(lens) for lens in (LENS_FORMS if form == "auto" else (form,))}
        form = min(fits, key=lambda lens: fits[lens][1])
        p = fits[form][0][:13]
        model = cls(p, scale, np.zeros((rows, cols, 2)), lattice, form)
        if correct:
            res = np.zeros((rows * cols, 2))
            res[found] = xy - _radial_apply(p, uv, scale, form)
            field = res.reshape(rows, cols, 2)
            if correct is True or residual_predictability(field, found) < CORRECTION_GAIN:
                model.residual = field
        return model

    def params(self) -> Params:
        rows, cols = self.residual.shape[:2]
        return {
            "radial_params": self.p,
            "radial_scale": np.array([self.scale]),
            "residual": self.residual.reshape(rows * cols, 2),
            "residual_shape": np.array([rows, cols], np.float64),
            "lattice": self.lattice,
            "radial_form": np.array([float(LENS_FORMS.index(self.form))]),
        }

    @classmethod
    def from_params(cls, params: Params) -> RadialMap:
        res = params["residual"]
        shape = params.get("residual_shape")
        if shape is None:  # format 1: square
            n = math.isqrt(len(res))
            rows, cols = n, n
        else:
            rows, cols = (round(float(v)) for v in np.ravel(shape)[:2])
        if np.size(params["radial_params"]) != 13:
            raise ValueError(f"radial_params has {np.size(params['radial_params'])} values, not 13")
        form = params.get("radial_form")  # absent before 2026-12-06: the polynomial
        code = 0 if form is None else round(float(np.ravel(form)[0]))
        if not 0 <= code < len(LENS_FORMS):
            raise ValueError(f"radial_form {code}: 0 (poly) or 1 (brown)")
        return cls(
            params["radial_params"].ravel(),
            float(params["radial_scale"].ravel()[0]),
            res.reshape(rows, cols, 2),
            params["lattice"].ravel(),
            LENS_FORMS[code],
        )

    def correction(self, xy: FloatArray) -> FloatArray:
        """Bilinear interpolation of the dot residuals at screen ``xy`` (clamped at the
        outer dots)."""
        rows, cols = self.residual.shape[:2]
        x0, y0, sx, sy = self.lattice
        fx = np.clip((xy[:, 0] - x0) / sx, 0, cols - 1)
        fy = np.clip((xy[:, 1] - y0) / sy, 0, rows - 1)
        fx = np.nan_to_num(fx)
        fy = np.nan_to_num(fy)
        ix = np.minimum(fx.astype(np.int64), cols - 2)
        iy = np.minimum(fy.astype(np.int64), rows - 2)
        ax, ay = (fx - ix)[:, None], (fy - iy)[:, None]
        r = self.residual
        return np.asarray(
            (1 - ax) * (1 - ay) * r[iy, ix]
            + ax * (1 - ay) * r[iy, ix + 1]
            + ax * ay * r[iy + 1, ix + 1]
            + (1 - ax) * ay * r[iy + 1, ix],
            np.float64,
        )

    def __call__(self, uv: FloatArray) -> FloatArray:
        xy = _radial_apply(self.p, _as_points(uv), self.scale, self.form)
        return xy + self.correction(xy)


def invert(fn: ImageToScreen, xy: FloatArray, uv0: FloatArray, iterations: int = 20) -> FloatArray:
    """Image points that ``fn`` maps to screen ``xy``, by Newton's method from ``uv0``;
    NaN where ``fn`` folds (a singular Jacobian: callers check for finite points)."""
    uv = np.asarray(uv0, np.float64).copy()
    e = 1e-3
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(iterations):
            f0 = fn(uv) - xy
            fu = (fn(uv + np.array([e, 0.0])) - f0 - xy) / e
            fv = (fn(uv + np.array([0.0, e])) - f0 - xy) / e
            det = fu[:, 0] * fv[:, 1] - fu[:, 1] * fv[:, 0]
            du = (f0[:, 0] * fv[:, 1] - f0[:, 1] * fv[:, 0]) / det
            dv = (fu[:, 0] * f0[:, 1] - fu[:, 1] * f0[:, 0]) / det
            uv -= np.stack([du, dv], axis=1)
    return uv
