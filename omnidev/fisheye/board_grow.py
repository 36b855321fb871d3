"""A chessboard grid grown from saddle points: the last detector of
:func:`omnidev.fisheye.board_detect.detect_chessboard`.

OpenCV's chessboard detectors look for rows of quads or for a grid in a locally straight
board image; near a mirror's rim or a fisheye's border the board is squeezed and bent so much
that both can fail. Here no straight line is assumed beyond one cell:

1. :func:`saddle_points`: X-junctions of the board's edges at four scales (Gaussian
   sigma 1, 1.6, 2.6, 4.2 px): local maxima of ``sigma^4 (Ixy^2 - Ixx Iyy)`` (positive at a
   saddle of the smoothed intensity) divided by the square of the local intensity range,
   kept when the intensity on a circle around the point (radius 2 sigma + 0.5) changes sign
   exactly four times, at two pairs of nearly opposite angles: the point's two edge lines.
2. :func:`grow_grid`: from a seed cell (a point, its nearest neighbours along each of its
   two lines, and the point that closes the parallelogram), every next corner is predicted
   from the corners already in the grid: along a row or column by linear (two corners) or
   quadratic (three) extrapolation, or as the fourth corner of a cell. The saddle point
   nearest the median prediction is taken if, for more than half of the predictions, it
   lies within a third of the local spacing and one of its edge lines points back along the
   step (within 20 degrees); targets with more predictions go first. Where two or more
   predictions agree but no saddle point is near (a junction too squeezed or blurred for
   the detector), the median prediction refined by ``cv2.cornerSubPix`` is taken if the
   circle test passes there. Growth stops when no
   prediction finds a point; the board is the one completely filled window of the
   pattern's size (either way round) in the grown grid. Up to :data:`SEEDS` seeds are
   tried, strongest first.

Pixels: (u, v) = (column, row), (0, 0) the centre of the top-left pixel. Pure: numpy and cv2
on arrays.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
Image = NDArray[np.uint8]

SIGMAS = (1.0, 1.6, 2.6, 4.2)
RESPONSE_MIN = 0.004  # normalised saddle response
CIRCLE_SAMPLES = 32
OPPOSITE_TOL = math.radians(35.0)  # opposite edge crossings: pi apart within this
LINE_TOL = math.radians(20.0)  # a step must run along one of the corner's lines
SEARCH = 1.0 / 3.0  # search radius / local spacing
SEEDS = 40
MAX_POINTS = 3000


def _circle_lines(
    img: NDArray[np.float32], pts: FloatArray, radius: FloatArray
) -> tuple[NDArray[np.bool_], FloatArray]:
    """For each point: is it an X-junction, and the angles (rad, [0, pi)) of its two lines."""
    ang = np.arange(CIRCLE_SAMPLES) * (2 * math.pi / CIRCLE_SAMPLES)
    mx = (pts[:, 0:1] + radius[:, None] * np.cos(ang)[None]).astype(np.float32)
    my = (pts[:, 1:2] + radius[:, None] * np.sin(ang)[None]).astype(np.float32)
    prof = np.concatenate(
        [
            np.asarray(
                cv2.remap(
                    img,
                    mx[k : k + 16384],
                    my[k : k + 16384],
                    cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE,
                ),
                np.float64,
            ).reshape(-1, CIRCLE_SAMPLES)
            for k in range(0, len(pts), 16384)
        ]
        or [np.zeros((0, CIRCLE_SAMPLES))]
    )
    lo, hi = prof.min(axis=1, keepdims=True), prof.max(axis=1, keepdims=True)
    mid = 0.5 * (lo + hi)
    s = prof > mid
    change = s != np.roll(s, -1, axis=1)  # between sample k and k + 1
    ok = change.sum(axis=1) == 4
    ok &= (hi - lo).ravel() > 0.08
    lines = np.zeros((len(pts), 2))
    for i in np.flatnonzero(ok):
        ks = np.flatnonzero(change[i])
        p = prof[i] - mid[i]
        cross = []
        for k in ks:
            a, b = p[k], p[(k + 1) % CIRCLE_SAMPLES]
            f = a / (a - b) if a != b else 0.5
            cross.append(ang[k] + f * (2 * math.pi / CIRCLE_SAMPLES))
        c = np.array(cross)
        d13 = (c[2] - c[0]) % (2 * math.pi)
        d24 = (c[3] - c[1]) % (2 * math.pi)
        if abs(d13 - math.pi) > OPPOSITE_TOL or abs(d24 - math.pi) > OPPOSITE_TOL:
            ok[i] = False
            continue
        l1 = (
            math.atan2(
                math.sin(2 * c[0]) + math.sin(2 * c[2]), math.cos(2 * c[0]) + math.cos(2 * c[2])
            )
            / 2
        )
        l2 = (
            math.atan2(
                math.sin(2 * c[1]) + math.sin(2 * c[3]), math.cos(2 * c[1]) + math.cos(2 * c[3])
            )
            / 2
        )
        lines[i] = (l1 % math.pi, l2 % math.pi)
    return ok, lines


def saddle_points(grey: Image) -> tuple[FloatArray, FloatArray, FloatArray]:
    """X-junction candidates of a (H, W) uint8 image: (M, 2) pixels, (M, 2) line angles (rad,
    [0, pi)), (M,) normalised strength; strongest first, at most :data:`MAX_POINTS`."""
    img = np.asarray(grey, np.float32) / 255.0
    all_pts, all_lines, all_str = [], [], []
    for sigma in SIGMAS:
        g = cv2.GaussianBlur(img, (0, 0), sigma)
        gxx = cv2.Sobel(g, cv2.CV_32F, 2, 0, ksize=3)
        gyy = cv2.Sobel(g, cv2.CV_32F, 0, 2, ksize=3)
        gxy = cv2.Sobel(g, cv2.CV_32F, 1, 1, ksize=3) * 0.25
        resp = (gxy * gxy - gxx * gyy) * sigma**4
        k = 2 * math.ceil(3 * sigma) + 1
        kernel = np.ones((k, k), np.uint8)
        rng = cv2.dilate(g, kernel) - cv2.erode(g, kernel)
        resp = resp / np.maximum(rng * rng, 1e-3)
        peak = (resp == cv2.dilate(resp, np.ones((3, 3), np.uint8))) & (resp > RESPONSE_MIN)
        vv, uu = np.nonzero(peak)
        if len(uu) == 0:
            continue
        # sub-pixel by a parabola through the response's neighbours
        h, w = resp.shape
        inner = (uu > 0) & (uu < w - 1) & (vv > 0) & (vv < h - 1)
        uu, vv = uu[inner], vv[inner]
        c = resp[vv, uu]
        du = (
            0.5
            * (resp[vv, uu - 1] - resp[vv, uu + 1])
            / np.minimum(resp[vv, uu - 1] - 2 * c + resp[vv, uu + 1], -1e-12)
        )
        dv = (
            0.5
            * (resp[vv - 1, uu] - resp[vv + 1, uu])
            / np.minimum(resp[vv - 1, uu] - 2 * c + resp[vv + 1, uu], -1e-12)
        )
        pts = np.stack([uu + np.clip(-du, -0.5, 0.5), vv + np.clip(-dv, -0.5, 0.5)], 1)
        ok, lines = _circle_lines(
            np.asarray(cv2.GaussianBlur(img, (0, 0), 0.5 * sigma), np.float32),
            pts,
            np.full(len(pts), 2 * sigma + 0.5),
        )
        all_pts.append(pts[ok])
        all_lines.append(lines[ok])
        all_str.append(c[ok].astype(np.float64))
    if not all_pts:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
    pts = np.concatenate(all_pts)
    lines = np.concatenate(all_lines)
    strength = np.concatenate(all_str)
    order = np.argsort(-strength)
    pts, lines, strength = pts[order], lines[order], strength[order]
    # one point per junction: the strongest within 2 px
    keep: list[int] = []
    for i in range(len(pts)):
        if keep and np.min(np.hypot(*(pts[keep] - pts[i]).T)) < 2.0:
            continue
        keep.append(i)
        if len(keep) >= MAX_POINTS:
            break
    return pts[keep], lines[keep], strength[keep]


def _along(step: FloatArray, lines: FloatArray) -> bool:
    """Whether the step (2,) runs along one of the lines (2,) angles (mod pi)."""
    a = math.atan2(float(step[1]), float(step[0])) % math.pi
    d = np.abs((lines - a + math.pi / 2) % math.pi - math.pi / 2)
    return bool(d.min() < LINE_TOL)


class _Grower:
    def __init__(self, pts: FloatArray, lines: FloatArray, limit: int, grey: Image) -> None:
        self.pts = pts
        self.lines = lines
        self.limit = limit  # largest extent along either grid axis
        self.grey = grey
        self.img = np.asarray(
            cv2.GaussianBlur(np.asarray(grey, np.float32) / 255.0, (0, 0), 0.7), np.float32
        )

    def probe(self, pred: FloatArray, sp: float) -> int | None:
        """A junction the saddle detector missed: the prediction refined by cv2.cornerSubPix,
        kept (appended to the points) if the circle test passes there at a quarter of the
        spacing; its index, or None."""
        h, w = self.grey.shape
        half = int(np.clip(math.floor(0.3 * sp), 2, 7))
        if not (half <= pred[0] < w - 1 - half and half <= pred[1] < h - 1 - half):
            return None
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3)
        q = cv2.cornerSubPix(
            self.grey, pred.reshape(1, 1, 2).astype(np.float32), (half, half), (-1, -1), crit
        )
        q = np.asarray(q, np.float64).reshape(1, 2)
        if float(np.hypot(*(q[0] - pred))) > SEARCH * sp:
            return None
        ok, lines = _circle_lines(self.img, q, np.array([max(1.5, 0.25 * sp)]))
        if not ok[0]:
            return None
        self.pts = np.concatenate([self.pts, q])
        self.lines = np.concatenate([self.lines, lines])
        return len(self.pts) - 1

    def nearest(self, pred: FloatArray, radius: float, used: set[int]) -> int | None:
        d = np.hypot(self.pts[:, 0] - pred[0], self.pts[:, 1] - pred[1])
        order = np.argsort(d)[:4]
        for j in order:
            if d[j] > radius:
                return None
            if int(j) not in used:
                return int(j)
        return None

    def seed(self, i: int) -> dict[tuple[int, int], int] | None:
        p = self.pts[i]
        d = np.hypot(self.pts[:, 0] - p[0], self.pts[:, 1] - p[1])
        d[i] = np.inf
        near = np.argsort(d)[:12]
        picks = []
        for line in self.lines[i]:
            e = np.array([math.cos(line), math.sin(line)])
            best = None
            for j in near:
                step = self.pts[j] - p
                dist = float(np.hypot(*step))
                if dist == 0 or not math.isfinite(dist):
                    continue
                cosang = float(step @ e) / dist
                if cosang > math.cos(LINE_TOL) and _along(-step, self.lines[j]):
                    best = int(j)
                    break
            if best is None:
                return None
            picks.append(best)
        a, b = picks
        la = float(np.hypot(*(self.pts[a] - p)))
        lb = float(np.hypot(*(self.pts[b] - p)))
        if not 1 / 3 < la / lb < 3:
            return None
        c = self.nearest(self.pts[a] + self.pts[b] - p, SEARCH * min(la, lb), {i, a, b})
        if c is None:
            return None
        return {(0, 0): i, (1, 0): a, (0, 1): b, (1, 1): c}

    def predictions(
        self, grid: dict[tuple[int, int], int]
    ) -> dict[tuple[int, int], list[tuple[FloatArray, float, FloatArray]]]:
        """Empty neighbours of the grid -> [(predicted pixel, spacing, step into it)]."""
        out: dict[tuple[int, int], list[tuple[FloatArray, float, FloatArray]]] = {}
        pos = self.pts
        for (c, r), i in grid.items():
            for dc, dr in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                t = (c + dc, r + dr)
                if t in grid:
                    continue
                p1 = pos[i]
                back = grid.get((c - dc, r - dr))
                preds = []
                if back is not None:
                    p0 = pos[back]
                    back2 = grid.get((c - 2 * dc, r - 2 * dr))
                    pred = 3 * p1 - 3 * p0 + pos[back2] if back2 is not None else 2 * p1 - p0
                    preds.append((pred, float(np.hypot(*(p1 - p0)))))
                for oc, orr in ((dr, dc), (-dr, -dc)):
                    side = grid.get((c + oc, r + orr))
                    diag = grid.get((c + dc + oc, r + dr + orr))
                    if side is not None and diag is not None:
                        pred = p1 + pos[diag] - pos[side]
                        preds.append((pred, float(np.hypot(*(pos[diag] - pos[side])))))
                for pred, sp in preds:
                    out.setdefault(t, []).append((pred, sp, pred - p1))
        return out

    def grow(self, grid: dict[tuple[int, int], int]) -> dict[tuple[int, int], int] | None:
        used = set(grid.values())
        while True:
            added = False
            targets = sorted(self.predictions(grid).items(), key=lambda kv: -len(kv[1]))
            for t, preds in targets:
                if t in grid:
                    continue
                pred = np.median([p for p, _, _ in preds], axis=0)
                sp = float(np.median([s for _, s, _ in preds]))
                j = self.nearest(pred, SEARCH * sp, used)
                if j is None and len(preds) >= 2:
                    j = self.probe(pred, sp)
                if j is None:
                    continue
                # most predictions must agree, with steps along the corner's lines
                votes = sum(
                    float(np.hypot(*(self.pts[j] - p))) <= SEARCH * s and _along(st, self.lines[j])
                    for p, s, st in preds
                )
                if 2 * votes <= len(preds):
                    continue
                grid[t] = j
                used.add(j)
                added = True
                cs = [k[0] for k in grid]
                rs = [k[1] for k in grid]
                if max(cs) - min(cs) >= self.limit or max(rs) - min(rs) >= self.limit:
                    return None  # larger than the board: not this pattern
            if not added:
                return grid


def grow_grid(grey: Image, inner: tuple[int, int]) -> FloatArray | None:
    """The (rows, cols, 2) corner grid of a chessboard with ``inner = (cols, rows)`` inner
    corners, grown from saddle points (module docstring), or None."""
    pts, lines, _ = saddle_points(grey)
    cols, rows = inner
    if len(pts) < cols * rows:
        return None
    grower = _Grower(pts, lines, max(cols, rows) + 2, np.asarray(grey, np.uint8))
    tried: set[int] = set()
    for i in range(min(SEEDS * 3, len(pts))):
        if len(tried) >= SEEDS:
            break
        if i in tried:
            continue
        seed = grower.seed(i)
        if seed is None:
            continue
        tried.update(seed.values())
        grid = grower.grow(seed)
        if grid is None:
            continue
        arr = _complete_window(grid, grower.pts, inner)
        if arr is not None:
            return arr
    return None


def _complete_window(
    grid: dict[tuple[int, int], int], pts: FloatArray, inner: tuple[int, int]
) -> FloatArray | None:
    """The one completely filled window of the pattern's size in a grown grid, as a
    (rows, cols, 2) array in the pattern's order; None if there is none or more than one.

    Growth may run past the board by a row of look-alikes (the board's own edge against a
    busy background); the board is then the one complete window inside."""
    cols, rows = inner
    cs = [k[0] for k in grid]
    rs = [k[1] for k in grid]
    c0, r0 = min(cs), min(rs)
    occ = np.full((max(rs) - r0 + 1, max(cs) - c0 + 1), -1, np.int64)
    for (c, r), j in grid.items():
        occ[r - r0, c - c0] = j
    found = []
    for wc, wr in {(cols, rows), (rows, cols)}:
        for r in range(occ.shape[0] - wr + 1):
            for c in range(occ.shape[1] - wc + 1):
                win = occ[r : r + wr, c : c + wc]
                if np.all(win >= 0):
                    found.append(win)
    if len(found) != 1:
        return None
    arr = pts[found[0]]
    return arr if arr.shape[:2] == (rows, cols) else arr.transpose(1, 0, 2)
