"""Image center of an omni-image: a mirror's disc and cut-off circle, or a fisheye's image circle.

:func:`detect_omni_circles` is the dissertation's (sec. 4.3): a catadioptric
image shows a bright mirror disc on a dark surround with a dark cut-off circle
in its middle where the camera sees itself; both are segmented by a global
threshold and fitted by an algebraic least-squares circle (Kasa).

:func:`detect_image_center` measures the center and says how sure it is,
for mirrors and fisheye image circles alike:

1. a coarse disc from a threshold (the largest bright region, holes filled);
2. 720 radial profiles across the disc's boundary (and, for a mirror, across
   the cut-off circle's), each edge located to sub-pixel precision at the
   strongest step of the right polarity, weak or out-of-image edges dropped;
3. a robust fit (iterated 3-sigma rejection) of an axis-aligned ellipse (non-
   square pixels) or a circle, whichever the edges call for;
4. the center's uncertainty: the larger of the fit's formal 1-sigma and the
   spread of the centers fitted to 8 leave-one-sector-out subsets (which
   sees non-circular rims, occluded arcs and uneven light);
5. a refusal (:class:`~omnidev.errors.CalibrationError`) when the boundary is
   too broken (few inliers, arcs on too few sides), the uncertainty is over
   ``max_sigma_px``, or a mirror's rim and cut-off circle disagree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError


@dataclass(frozen=True)
class OmniCircles:
    """Image center (u0, v0) px, the mirror disc's radius and the cut-off radius, px."""

    center: tuple[float, float]
    disc_radius: float
    cutoff_radius: float


def fit_circle(points: NDArray[np.float64]) -> tuple[float, float, float]:
    """Algebraic least-squares circle through (n, 2) points: (cx, cy, radius)."""
    x, y = points[:, 0], points[:, 1]
    A = np.stack([x, y, np.ones_like(x)], axis=1)
    b = x * x + y * y
    (p, q, s), *_ = np.linalg.lstsq(A, b, rcond=None)
    cx, cy = p / 2, q / 2
    return float(cx), float(cy), float(np.sqrt(s + cx * cx + cy * cy))


def detect_omni_circles(image: NDArray[np.uint8]) -> OmniCircles:
    """Find the mirror disc and the cut-off circle of an omni-image.

    Raises :class:`CalibrationError` when no bright disc with a dark center is found.
    """
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    gray = cv2.GaussianBlur(gray, (5, 5), 0)
    _, mask = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    contours, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if not contours or hierarchy is None:
        raise CalibrationError("no bright mirror disc found in the omni-image")
    outer = [i for i, h in enumerate(hierarchy[0]) if h[3] < 0]
    disc_i = max(outer, key=lambda i: cv2.contourArea(contours[i]))
    disc = contours[disc_i].reshape(-1, 2).astype(np.float64)
    dcx, dcy, dr = fit_circle(disc)
    h, w = gray.shape
    on_border = (
        (disc[:, 0] <= 0) | (disc[:, 1] <= 0) | (disc[:, 0] >= w - 1) | (disc[:, 1] >= h - 1)
    )
    if np.count_nonzero(~on_border) > 20:
        dcx, dcy, dr = fit_circle(disc[~on_border])
    holes = [i for i, hh in enumerate(hierarchy[0]) if hh[3] == disc_i]
    best: tuple[float, float, float] | None = None
    best_d = np.inf
    for i in holes:
        pts = contours[i].reshape(-1, 2).astype(np.float64)
        if len(pts) < 12 or cv2.contourArea(contours[i]) < 50:
            continue
        cx, cy, r = fit_circle(pts)
        d = float(np.hypot(cx - dcx, cy - dcy))
        if d < 0.25 * dr and d < best_d:
            best, best_d = (cx, cy, r), d
    if best is None:
        raise CalibrationError(
            "no dark cut-off circle found inside the mirror disc; give the image center explicitly"
        )
    # Contours run through pixel centers on the inside of the boundary: the
    # hole's contour lies half a pixel outside the hole, the disc's inside the disc.
    return OmniCircles((best[0], best[1]), dr + 0.5, best[2] - 0.5)


@dataclass(frozen=True)
class CircleFit:
    """One boundary: center (px), semi-axes along u and v (px), 1-sigma of the center (px)."""

    center: tuple[float, float]
    radii: tuple[float, float]
    sigma_px: float
    inliers: int
    rays: int
    sectors: int  # of 8 angular sectors, how many hold inliers
    residual_px: float  # RMS distance of the inlier edges from the fit


@dataclass(frozen=True)
class CenterEstimate:
    """What :func:`detect_image_center` found.

    Attributes:
        center: (u0, v0) px; sigma_px: its 1-sigma uncertainty, px.
        kind: "mirror" (a disc with a cut-off circle) or "fisheye".
        aspect: v over u semi-axis of the outer boundary (1 for square pixels).
        disc: the outer boundary (the mirror's rim or the fisheye's image circle).
        cutoff: the mirror's cut-off circle (None for a fisheye).
    """

    center: tuple[float, float]
    sigma_px: float
    kind: str
    aspect: float
    disc: CircleFit
    cutoff: CircleFit | None

    @property
    def disc_radius(self) -> float:
        """The outer boundary's radius along u (the ideal frame's px)."""
        return self.disc.radii[0]

    @property
    def cutoff_radius(self) -> float:
        """The cut-off circle's radius along u (0 for a fisheye)."""
        return 0.0 if self.cutoff is None else self.cutoff.radii[0]


def _fit_conic(x: NDArray[np.float64], y: NDArray[np.float64], ellipse: bool) -> tuple[float, ...]:
    """Least squares (x - cx)^2 / a^2 + (y - cy)^2 / b^2 = 1 (b = a for a circle): cx, cy, a, b."""
    if ellipse:  # P x^2 + Q y^2 + R x + S y = 1 about the points' mean, scaled to ~1
        mx, my = float(np.mean(x)), float(np.mean(y))
        sc = float(np.sqrt(np.mean((x - mx) ** 2 + (y - my) ** 2))) or 1.0
        xs, ys = (x - mx) / sc, (y - my) / sc
        A = np.stack([xs * xs, ys * ys, xs, ys], 1)
        p, *_ = np.linalg.lstsq(A, np.ones_like(xs), rcond=None)
        P, Q, R, S = p
        if P <= 0 or Q <= 0:
            return (math.nan,) * 4
        cx, cy = -R / (2 * P), -S / (2 * Q)
        k = 1 + P * cx * cx + Q * cy * cy
        if k <= 0:
            return (math.nan,) * 4
        return (
            float(mx + sc * cx),
            float(my + sc * cy),
            float(sc * math.sqrt(k / P)),
            float(sc * math.sqrt(k / Q)),
        )
    cx, cy, r = fit_circle(np.stack([x, y], 1))
    return cx, cy, r, r


def _ellipse_distance(
    x: NDArray[np.float64], y: NDArray[np.float64], p: tuple[float, ...]
) -> NDArray[np.float64]:
    """Approximate geometric distance (px) of points from an axis-aligned ellipse."""
    cx, cy, a, b = p
    dx, dy = x - cx, y - cy
    rho = np.hypot(dx / a, dy / b)
    ang = np.arctan2(dy / b, dx / a)
    scale = np.hypot(a * np.cos(ang), b * np.sin(ang))
    return np.asarray((rho - 1.0) * scale, np.float64)


def _robust_fit(
    x: NDArray[np.float64], y: NDArray[np.float64], psi: NDArray[np.float64]
) -> tuple[tuple[float, ...], NDArray[np.bool_], bool] | None:
    """Circle or ellipse through edge points with iterated 3-sigma rejection."""
    best = None
    for ellipse in (False, True):
        keep = np.ones(len(x), bool)
        p: tuple[float, ...] = (math.nan,) * 4
        for _ in range(8):
            if keep.sum() < 12:
                break
            p = _fit_conic(x[keep], y[keep], ellipse)
            if not all(math.isfinite(v) for v in p):
                break
            d = np.abs(_ellipse_distance(x, y, p))
            s = 1.4826 * float(np.median(d[keep])) + 0.02
            new = d < max(3.0 * s, 0.15)
            if np.array_equal(new, keep):
                break
            keep = new
        if keep.sum() < 12 or not all(math.isfinite(v) for v in p):
            continue
        res = float(np.sqrt(np.mean(_ellipse_distance(x[keep], y[keep], p) ** 2)))
        # the ellipse must earn its extra parameter: 5 % more inliers, or as many and a
        # 10 % lower residual
        if best is None:
            best = (p, keep, ellipse, res)
        else:
            n_b, n_e = int(best[1].sum()), int(keep.sum())
            if n_e > 1.05 * n_b or (n_e >= 0.98 * n_b and res < 0.9 * best[3]):
                best = (p, keep, ellipse, res)
    if best is None:
        return None
    return best[0], best[1], best[2]


def _edges(
    gray: NDArray[np.float32],
    center: tuple[float, float],
    radii: tuple[float, float],
    falling: bool,
    window: float,
    rays: int = 720,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Sub-pixel edge points along ``rays`` radial profiles around an ellipse guess.

    ``falling``: the grey level drops going outwards (a disc's rim), else it
    rises (a cut-off circle). Returns edge x, y and the ray angle of each kept edge.
    """
    h, w = gray.shape
    psi = np.arange(rays) * (2 * math.pi / rays)
    a, b = radii
    r0 = a * b / np.hypot(b * np.cos(psi), a * np.sin(psi))  # the ellipse's polar radius
    half = np.maximum(4.0, window * r0)
    step = 0.25
    k = np.arange(-1.0, 1.0 + 1e-9, step / float(np.max(half)))
    rr = r0[:, None] + half[:, None] * k[None, :]  # (rays, samples)
    xs = (center[0] + rr * np.cos(psi)[:, None]).astype(np.float32)
    ys = (center[1] + rr * np.sin(psi)[:, None]).astype(np.float32)
    inside = (xs >= 1) & (xs <= w - 2) & (ys >= 1) & (ys <= h - 2)
    prof = cv2.remap(gray, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    spacing = half * (k[1] - k[0])  # px between samples, per ray
    prof = cv2.GaussianBlur(prof, (0, 0), sigmaX=float(np.median(1.0 / spacing)), sigmaY=0.01)
    g = np.gradient(prof, axis=1) / (half[:, None] * (k[1] - k[0]))  # grey per px along the ray
    if falling:
        g = -g
    j = np.argmax(g, axis=1)
    jj = np.clip(j, 1, g.shape[1] - 2)
    gm, g0, gp = g[np.arange(rays), jj - 1], g[np.arange(rays), jj], g[np.arange(rays), jj + 1]
    den = gm - 2 * g0 + gp
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.where(np.abs(den) > 1e-9, 0.5 * (gm - gp) / den, 0.0)
    rad = rr[np.arange(rays), jj] + np.clip(off, -1, 1) * half * (k[1] - k[0])
    # a step of at least 12 grey levels, sharp (not a ramp over more than ~10 px)
    q = max(1, len(k) // 5)
    inner = prof[:, :q].mean(1)
    outer = prof[:, -q:].mean(1)
    contrast = (inner - outer) if falling else (outer - inner)
    strong = (contrast > 12.0) & (g0 > 0.1 * contrast)
    ok = strong & inside.all(axis=1) & (j > 0) & (j < g.shape[1] - 1)
    x = center[0] + rad * np.cos(psi)
    y = center[1] + rad * np.sin(psi)
    return x[ok], y[ok], psi[ok]


def _cutoff_guess(
    gray: NDArray[np.float32], center: tuple[float, float], radius: float, rays: int = 360
) -> tuple[tuple[float, float], float] | None:
    """A first cut-off circle: on each ray from ``center``, where the dark middle first turns
    bright (half-way between the middle's grey and the scene's), fitted robustly."""
    psi = np.arange(rays) * (2 * math.pi / rays)
    rr = np.linspace(0.0, 0.6 * radius, 600)
    xs = (center[0] + rr[None, :] * np.cos(psi)[:, None]).astype(np.float32)
    ys = (center[1] + rr[None, :] * np.sin(psi)[:, None]).astype(np.float32)
    prof = cv2.remap(gray, xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    dark = float(np.median(prof[:, :15]))
    scene = float(np.median(prof[:, 300:]))
    if scene - dark < 20.0:
        return None
    above = prof > 0.5 * (dark + scene)
    first = np.argmax(above, axis=1)
    ok = above[np.arange(rays), first] & (first > 5)
    if ok.sum() < 60:
        return None
    x = center[0] + rr[first[ok]] * np.cos(psi[ok])
    y = center[1] + rr[first[ok]] * np.sin(psi[ok])
    got = _robust_fit(x, y, psi[ok])
    if got is None:
        return None
    p, keep, _ = got
    if keep.sum() < 0.5 * rays:
        return None
    return (p[0], p[1]), 0.5 * (p[2] + p[3])


def _boundary(
    gray: NDArray[np.float32],
    center: tuple[float, float],
    radii: tuple[float, float],
    falling: bool,
    first: float = 0.25,
) -> CircleFit | None:
    """Edges around a guess, refined in narrowing windows (``first`` of the radius, then
    0.08 and 0.03), with the center's uncertainty (jackknife over 8 sectors)."""
    fit: CircleFit | None = None
    c, r = center, radii
    for window in (first, 0.08, 0.03) if first > 0.08 else (first, 0.03):
        x, y, psi = _edges(gray, c, r, falling, window)
        if len(x) < 24:
            return None
        got = _robust_fit(x, y, psi)
        if got is None:
            return None
        p, keep, ellipse = got
        c, r = (p[0], p[1]), (p[2], p[3])
    sector = np.floor(psi / (2 * math.pi) * 8).astype(int) % 8
    used = np.unique(sector[keep])
    jack = []
    for sct in used:
        m = keep & (sector != sct)
        if m.sum() < 12:
            continue
        q = _fit_conic(x[m], y[m], ellipse)
        if all(math.isfinite(v) for v in q):
            jack.append((q[0], q[1]))
    d = _ellipse_distance(x[keep], y[keep], p)
    res = float(np.sqrt(np.mean(d * d)))
    n = int(keep.sum())
    formal = res * math.sqrt(2.0 / n)
    if len(jack) >= 3:
        jk = np.array(jack)
        spread = float(np.sqrt((len(jk) - 1) / len(jk) * np.sum(np.var(jk, axis=0) * len(jk))))
    else:
        spread = math.inf
    sigma = max(formal, spread, 0.01)  # below 0.01 px the pixel grid's own bias dominates
    fit = CircleFit((p[0], p[1]), (p[2], p[3]), sigma, n, 720, len(used), res)
    return fit


def detect_image_center(
    image: NDArray[np.uint8],
    *,
    kind: str = "auto",
    max_sigma_px: float = 0.3,
) -> CenterEstimate:
    """Measure the image center of a mirror or fisheye omni-image, or refuse.

    Args:
        image: (H, W) or (H, W, 3) uint8.
        kind: "mirror" (use the disc's rim and the cut-off circle), "fisheye"
            (the image circle only), or "auto" (a mirror when a dark cut-off
            hole is found inside the disc).
        max_sigma_px: refuse when the center's 1-sigma is larger.

    Raises:
        CalibrationError: naming why the center is not sure enough.
    """
    if kind not in ("auto", "mirror", "fisheye"):
        raise ValueError(f"kind {kind!r}: choose auto, mirror or fisheye")
    gray8 = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    gray = np.asarray(cv2.GaussianBlur(gray8.astype(np.float32), (0, 0), 1.0), np.float32)
    blur8 = cv2.GaussianBlur(gray8, (0, 0), 2.0)
    _, mask = cv2.threshold(blur8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n < 2:
        raise CalibrationError("no bright image disc found (is the image dark or overexposed?)")
    big = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    disc = (labels == big).astype(np.uint8)
    contours, _ = cv2.findContours(disc, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    pts = max(contours, key=len).reshape(-1, 2).astype(np.float64)
    h, w = gray8.shape
    inner_pts = pts[(pts[:, 0] > 1) & (pts[:, 1] > 1) & (pts[:, 0] < w - 2) & (pts[:, 1] < h - 2)]
    if len(inner_pts) < 24:
        raise CalibrationError("the image disc's boundary is not inside the image")
    first = _robust_fit(inner_pts[:, 0], inner_pts[:, 1], np.zeros(len(inner_pts)))
    if first is None:
        cx, cy, r = fit_circle(inner_pts)
        guess: tuple[float, ...] = (cx, cy, r, r)
    else:
        guess = first[0]
    outer = _boundary(gray, (guess[0], guess[1]), (guess[2], guess[3]), falling=True)
    if outer is None:
        raise CalibrationError(
            "the image disc's boundary is too weak or broken to measure (low contrast "
            "against the surround?); give the image center explicitly"
        )
    cutoff: CircleFit | None = None
    if kind != "fisheye":
        hole = _cutoff_guess(gray, outer.center, outer.radii[0])
        if hole is not None:
            (gx, gy), gr = hole
            cutoff = _boundary(gray, (gx, gy), (gr, gr), falling=False, first=0.08)
        if kind == "mirror" and cutoff is None:
            raise CalibrationError(
                "no sharp cut-off circle found inside the mirror disc; use --kind fisheye "
                "(the rim only) or give the image center explicitly"
            )
    fits = [outer] + ([cutoff] if cutoff is not None else [])
    for f, name in zip(fits, ("image disc's rim", "cut-off circle"), strict=False):
        if f.inliers < 0.4 * f.rays or f.sectors < 5:
            raise CalibrationError(
                f"the {name} is seen on too little of its circumference ({f.inliers} of "
                f"{f.rays} profiles, {f.sectors} of 8 sectors): occluded or cut by the frame; "
                "give the image center explicitly"
            )
    if cutoff is not None:
        d = math.hypot(outer.center[0] - cutoff.center[0], outer.center[1] - cutoff.center[1])
        s = math.hypot(outer.sigma_px, cutoff.sigma_px)
        if d > 3 * s + 0.5:
            raise CalibrationError(
                f"the mirror's rim and its cut-off circle are {d:.1f} px apart (1-sigma "
                f"{s:.2f} px): the lens is not aligned with the mirror, so neither is the "
                "image center; calibrate with --model general, which fits the center"
            )
        wa, wb = 1 / outer.sigma_px**2, 1 / cutoff.sigma_px**2
        center = (
            (wa * outer.center[0] + wb * cutoff.center[0]) / (wa + wb),
            (wa * outer.center[1] + wb * cutoff.center[1]) / (wa + wb),
        )
        sigma = 1 / math.sqrt(wa + wb)
    else:
        center, sigma = outer.center, outer.sigma_px
    if sigma > max_sigma_px:
        raise CalibrationError(
            f"the image center ({center[0]:.1f}, {center[1]:.1f}) is unsure: 1-sigma "
            f"{sigma:.2f} px > {max_sigma_px:g} px (rim residual {outer.residual_px:.2f} px); "
            "give the image center explicitly"
        )
    return CenterEstimate(
        center,
        sigma,
        "mirror" if cutoff is not None else "fisheye",
        outer.radii[1] / outer.radii[0],
        outer,
        cutoff,
    )
