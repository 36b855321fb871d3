"""Interpolation of the unfilled pixels of a back-projected view (dissertation ch. 3).

Back-projecting every omni-image pixel onto a view plane (sec. 2.5.1) leaves a
*raw unwarped image* in which some pixels received no omni-image data. This
module fills them, numpy in and numpy out:

- ``interpolate_4nn``: the 4-nearest-neighbour baseline of Fig. 3.6(c);
- ``interpolate_two_layered``: the non-edge-preserving 8-directional two-layered
  weighting of sec. 3.2.1 (eqs. 3.3-3.8), window grown from 7x7 until support exists;
- ``interpolate_edge_preserving``: sec. 3.2.2, the on-edge pair test on the
  unwarped edge map and eq. 3.9, else the two-layered value;
- ``sobel_edge_value``: the normalized Sobel edge-value image I_e of sec. 3.2.2 (1).

Conventions (the dissertation leaves them to Fig. 3.3, which the text does not carry;
docs/nonsvp-interpolation.md gives the reasoning):

- Pixels are addressed (x, y) = (column, row), centre of the top-left pixel (0, 0);
  an offset o = (dx, dy) points from the unfilled pixel P_u to a support pixel,
  distance d = sqrt(dx^2 + dy^2) in pixels.
- The n x n window R (n odd) holds the offsets with max(|dx|, |dy|) <= (n - 1) / 2
  except (0, 0). Parts of R outside the image hold no support.
- The eight sub-regions S_1..S_8 are 45-degree wedges of direction: with the angle
  phi = atan2(dy, dx) in [0, 2 pi) (measured from +x towards +y, i.e. clockwise on
  screen), S_k holds phi in [(k - 1) pi / 4, k pi / 4). They partition R, so
  M = sum m_i counts every support pixel once (eq. 3.3).
- For the on-edge pair test a wedge is closed: an offset on an axis or a diagonal
  belongs to both wedges it bounds. S_k and S_{k+4} are opposite. This is the reading
  under which the example of Fig. 3.10 (supports at distances sqrt(2) and 1, span
  angle 135 degrees) is a candidate pair for theta_t = 120 degrees and not for 180.
  The span-angle test is theta_m >= theta_t (so collinear pairs pass at 180 degrees).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "EdgePairs",
    "find_on_edge_pairs",
    "interpolate_4nn",
    "interpolate_edge_preserving",
    "interpolate_two_layered",
    "sobel_edge_value",
    "synthetic_unfilled_mask",
    "wedge_index",
    "window_offsets",
]

_EPS_ANGLE = 1e-9


# ---------------------------------------------------------------- input checks


def _check(raw: NDArray[Any], filled: NDArray[np.bool_]) -> tuple[NDArray[np.float32], int]:
    """Validate (raw, filled); return raw as float32 H x W x C and C (one-line ValueError)."""
    raw = np.asarray(raw)
    filled = np.asarray(filled)
    if raw.ndim not in (2, 3) or (raw.ndim == 3 and raw.shape[2] not in (1, 3, 4)):
        raise ValueError(f"raw must be H x W or H x W x 1/3/4, got shape {raw.shape}")
    if raw.dtype not in (np.uint8, np.uint16, np.float32, np.float64):
        raise ValueError(f"raw must be uint8, uint16, float32 or float64, got {raw.dtype}")
    if filled.dtype != np.bool_:
        raise ValueError(f"filled must be a bool array, got {filled.dtype}")
    if filled.shape != raw.shape[:2]:
        raise ValueError(f"filled has shape {filled.shape}, raw has {raw.shape[:2]}: must match")
    if not filled.any():
        raise ValueError("filled has no True pixel: nothing to interpolate from")
    val = raw.astype(np.float32, copy=False)
    if val.ndim == 2:
        val = val[:, :, None]
    return val, val.shape[2]


def _check_window(window: int, name: str = "window") -> None:
    if window < 3 or window % 2 == 0:
        raise ValueError(f"{name} must be an odd integer >= 3, got {window}")


def _finish(
    raw: NDArray[Any], ys: NDArray[np.intp], xs: NDArray[np.intp], vals: NDArray[Any]
) -> NDArray[Any]:
    """Copy raw and write vals (n x C float) at (ys, xs), rounded/clipped to raw's dtype."""
    out = np.array(raw, copy=True)
    if out.dtype in (np.uint8, np.uint16):
        hi = float(np.iinfo(out.dtype).max)
        vals = np.clip(np.rint(vals), 0.0, hi)
    v = vals.astype(out.dtype)
    if out.ndim == 2:
        out[ys, xs] = v[:, 0]
    else:
        out[ys, xs] = v
    return out


# ------------------------------------------------------------ window geometry


def window_offsets(window: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Offsets (dx, dy) in pixels of an n x n window without its centre, row-major order."""
    r = window // 2
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    keep = (dx != 0) | (dy != 0)
    return dx[keep].astype(np.intp), dy[keep].astype(np.intp)


def wedge_index(dx: NDArray[np.intp], dy: NDArray[np.intp]) -> NDArray[np.intp]:
    """Half-open sub-region index 0..7 (S_1..S_8) of offsets: phi in [k pi/4, (k+1) pi/4)."""
    phi = np.mod(np.arctan2(dy.astype(np.float64), dx.astype(np.float64)), 2 * np.pi)
    return np.floor(phi / (np.pi / 4) + _EPS_ANGLE).astype(np.intp) % 8


def _on_ray(dx: NDArray[np.intp], dy: NDArray[np.intp]) -> NDArray[np.bool_]:
    on: NDArray[np.bool_] = (dx == 0) | (dy == 0) | (np.abs(dx) == np.abs(dy))
    return on


def _closed_wedges(dx: NDArray[np.intp], dy: NDArray[np.intp]) -> list[NDArray[np.bool_]]:
    """Membership of each offset in the closed wedges 0..7 (rays belong to both sides)."""
    k = wedge_index(dx, dy)
    ray = _on_ray(dx, dy)
    return [(k == w) | (ray & ((k - 1) % 8 == w)) for w in range(8)]


# ------------------------------------------------------------------ edge value


def sobel_edge_value(gray: NDArray[np.uint8]) -> NDArray[np.float32]:
    """Edge-value image I_e of sec. 3.2.2 (1): Sobel gradient magnitude divided by its maximum.

    Args:
        gray: H x W uint8 omni-image (convert colour with cv2.cvtColor first).
    Returns:
        H x W float32 in [0, 1]: sqrt(gx^2 + gy^2) of the 3x3 Sobel operator
        (border reflected), normalized by the image's largest magnitude (all zeros
        for a flat image).
    """
    g = np.asarray(gray)
    if g.ndim != 2 or g.dtype != np.uint8:
        raise ValueError(f"gray must be an H x W uint8 image, got {g.dtype} {g.shape}")
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    mag = cv2.magnitude(gx, gy)
    top = float(mag.max())
    if top <= 0.0:
        return np.zeros(g.shape, np.float32)
    return (mag / np.float32(top)).astype(np.float32)


# ------------------------------------------------------------ ring gathering


def _gather(
    arr: NDArray[Any], ys: NDArray[np.intp], xs: NDArray[np.intp], dx: int, dy: int
) -> tuple[NDArray[Any], NDArray[np.bool_]]:
    """arr at (ys + dy, xs + dx) and whether that point is inside the image."""
    h, w = arr.shape[:2]
    yy, xx = ys + dy, xs + dx
    inside = (yy >= 0) & (yy < h) & (xx >= 0) & (xx < w)
    return arr[np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)], inside


def _ring_offsets(radius: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Offsets with max(|dx|, |dy|) == radius (the ring added when R grows to 2 radius + 1)."""
    dx, dy = window_offsets(2 * radius + 1)
    on = np.maximum(np.abs(dx), np.abs(dy)) == radius
    return dx[on], dy[on]


def _nearest_fill(
    val: NDArray[np.float32], filled: NDArray[np.bool_], ys: NDArray[np.intp], xs: NDArray[np.intp]
) -> NDArray[np.float32]:
    """Value of the Euclidean-nearest filled pixel (fallback beyond max_window)."""
    src = np.where(filled, 0, 255).astype(np.uint8)
    _, labels = cv2.distanceTransformWithLabels(src, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    fy, fx = np.nonzero(filled)
    # labels number the zero pixels of src 1.. in row-major scan order
    lab = labels[ys, xs] - 1
    got: NDArray[np.float32] = val[fy[lab], fx[lab]]
    return got


# ------------------------------------------------------------ two-layered core


def _two_layered_sums_ring(
    val: NDArray[np.float32],
    filled: NDArray[np.bool_],
    ys: NDArray[np.intp],
    xs: NDArray[np.intp],
    dx: NDArray[np.intp],
    dy: NDArray[np.intp],
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Eqs. 3.3-3.8 over the given offsets for pixels (ys, xs): (I_u n x C, M n)."""
    n, c = ys.size, val.shape[2]
    k = wedge_index(dx, dy)
    num = np.zeros((n, c), np.float32)
    big_m = np.zeros(n, np.float32)
    for w in range(8):
        sel = np.flatnonzero(k == w)
        if sel.size == 0:
            continue
        m_i = np.zeros(n, np.float32)
        d_i = np.zeros(n, np.float32)
        n_i = np.zeros((n, c), np.float32)
        for j in sel:
            f, ok = _gather(filled, ys, xs, int(dx[j]), int(dy[j]))
            f = f & ok
            v, _ = _gather(val, ys, xs, int(dx[j]), int(dy[j]))
            inv = np.float32(1.0 / math.hypot(float(dx[j]), float(dy[j])))
            m_i += f
            d_i += f * inv
            n_i += (f * inv)[:, None] * v
        has = m_i > 0
        num[has] += (m_i[has] / d_i[has])[:, None] * n_i[has]
        big_m += m_i
    out = np.zeros((n, c), np.float32)
    ok = big_m > 0
    out[ok] = num[ok] / big_m[ok][:, None]
    return out, big_m


def _wedge_kernels(window: int) -> list[tuple[NDArray[np.float32], NDArray[np.float32], int, int]]:
    """Per half-open wedge: (count kernel, 1/d kernel, anchor x, anchor y) for cv2.filter2D.

    Each kernel spans the wedge's bounding box extended to hold the centre, so
    filter2D(src, kernel, anchor) = sum over wedge offsets o of weight(o) src(p + o).
    """
    dx, dy = window_offsets(window)
    k = wedge_index(dx, dy)
    out = []
    for w in range(8):
        sel = k == w
        x0, x1 = min(int(dx[sel].min()), 0), max(int(dx[sel].max()), 0)
        y0, y1 = min(int(dy[sel].min()), 0), max(int(dy[sel].max()), 0)
        cnt = np.zeros((y1 - y0 + 1, x1 - x0 + 1), np.float32)
        inv = np.zeros_like(cnt)
        for ddx, ddy in zip(dx[sel], dy[sel], strict=True):
            cnt[ddy - y0, ddx - x0] = 1.0
            inv[ddy - y0, ddx - x0] = 1.0 / math.hypot(float(ddx), float(ddy))
        out.append((cnt, inv, -x0, -y0))
    return out


def _two_layered_window(
    val: NDArray[np.float32],
    filled: NDArray[np.bool_],
    flat_idx: NDArray[np.intp],
    window: int,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Eqs. 3.3-3.8 in the full n x n window for the pixels flat_idx (whole-image filters)."""
    h, w, c = val.shape
    f32 = filled.astype(np.float32)
    stack = np.empty((h, w, c + 1), np.float32)
    stack[:, :, 0] = f32
    stack[:, :, 1:] = val * f32[:, :, None]
    n = flat_idx.size
    num = np.zeros((n, c + 1), np.float32)  # column 0 unused
    big_m = np.zeros(n, np.float32)
    border = cv2.BORDER_CONSTANT
    for cnt, inv, ax, ay in _wedge_kernels(window):
        m_i = cv2.filter2D(f32, -1, cnt, anchor=(ax, ay), borderType=border)
        m_i = m_i.ravel().take(flat_idx)
        dn = cv2.filter2D(stack, -1, inv, anchor=(ax, ay), borderType=border)
        dn = dn.reshape(-1, c + 1).take(flat_idx, axis=0)
        # s_i / d_i = m_i / (M d_i); a wedge with m_i = 0 has d_i = 0: ratio 0 / 1
        ratio = m_i / (dn[:, 0] + (m_i < 0.5))
        np.multiply(dn, ratio[:, None], out=dn)
        np.add(num, dn, out=num)
        big_m += m_i
    out = (num[:, 1:] / np.maximum(big_m, np.float32(1.0))[:, None]).astype(np.float32)
    return out, big_m


def _two_layered_values(
    val: NDArray[np.float32],
    filled: NDArray[np.bool_],
    ys: NDArray[np.intp],
    xs: NDArray[np.intp],
    window: int,
    max_window: int,
    *,
    reference: bool = False,
) -> NDArray[np.float32]:
    """Two-layered values for the pixels (ys, xs), growing R by 2 until support is found."""
    w = val.shape[1]
    if reference:
        dx, dy = window_offsets(window)
        vals, big_m = _two_layered_sums_ring(val, filled, ys, xs, dx, dy)
    else:
        vals, big_m = _two_layered_window(val, filled, ys * w + xs, window)
    _grow(val, filled, ys, xs, vals, big_m, window, max_window, _two_layered_sums_ring)
    return vals


def _grow(
    val: NDArray[np.float32],
    filled: NDArray[np.bool_],
    ys: NDArray[np.intp],
    xs: NDArray[np.intp],
    vals: NDArray[np.float32],
    big_m: NDArray[np.float32],
    window: int,
    max_window: int,
    ring_fn: Callable[..., tuple[NDArray[np.float32], NDArray[np.float32]]],
) -> None:
    """Fill in place the rows of vals with no support (big_m == 0) by growing the window.

    Growing R from n to n + 2 adds the ring max(|dx|, |dy|) = (n + 1) / 2; a pixel with
    no support in the smaller window has all its support in that ring, so only the
    ring is visited. Beyond max_window the nearest filled pixel's value is used.
    """
    todo = np.flatnonzero(big_m <= 0.5)
    radius = window // 2
    while todo.size and 2 * (radius + 1) + 1 <= max_window:
        radius += 1
        rdx, rdy = _ring_offsets(radius)
        got, m = ring_fn(val, filled, ys[todo], xs[todo], rdx, rdy)
        ok = m > 0.5
        vals[todo[ok]] = got[ok]
        todo = todo[~ok]
    if todo.size:
        vals[todo] = _nearest_fill(val, filled, ys[todo], xs[todo])


# ------------------------------------------------------------------ public API


def interpolate_two_layered(
    raw: NDArray[Any],
    filled: NDArray[np.bool_],
    *,
    window: int = 7,
    max_window: int = 63,
) -> NDArray[Any]:
    """Non-edge-preserving 8-directional two-layered weighting (sec. 3.2.1, eqs. 3.3-3.8).

    For an unfilled pixel P_u and the support pixels P_ij (filled pixels of sub-region
    S_i of the window R): s_i = m_i / M, d_i = sum_j 1/d_ij, w_ij = (1/d_ij) / d_i * s_i
    and I_u = sum_i sum_j w_ij I_ij. A pixel with no support in R gets R grown by 2
    (7x7, 9x9, ...) until support is found; beyond max_window x max_window it takes
    the value of the nearest filled pixel (this fallback is omnidev's, not the text's).

    Args:
        raw: H x W or H x W x C image (uint8, uint16 or float); unfilled pixels ignored.
        filled: H x W bool, True where a back-projected pixel landed.
        window: starting window size n (odd, >= 3).
        max_window: largest window tried (odd, >= window).
    Returns:
        A copy of raw with every unfilled pixel interpolated (integers rounded);
        filled pixels are unchanged.
    Example:
        Each unfilled pixel has one support pixel on either side (s_i = 1/2 each):

        >>> raw = np.array([[10, 0, 0, 40]], np.uint8)
        >>> interpolate_two_layered(raw, raw > 0)
        array([[10, 25, 25, 40]], dtype=uint8)
    """
    val, _ = _check(raw, filled)
    _check_window(window)
    _check_window(max_window, "max_window")
    ys, xs = np.nonzero(~filled)
    vals = _two_layered_values(val, filled, ys, xs, window, max(window, max_window))
    return _finish(raw, ys, xs, vals)


def interpolate_two_layered_reference(
    raw: NDArray[Any],
    filled: NDArray[np.bool_],
    *,
    window: int = 7,
    max_window: int = 63,
) -> NDArray[Any]:
    """interpolate_two_layered computed pixel by offset (gathers, no filters): the reference."""
    val, _ = _check(raw, filled)
    _check_window(window)
    _check_window(max_window, "max_window")
    ys, xs = np.nonzero(~filled)
    vals = _two_layered_values(val, filled, ys, xs, window, max(window, max_window), reference=True)
    return _finish(raw, ys, xs, vals)


def _knn_ring(
    val: NDArray[np.float32],
    filled: NDArray[np.bool_],
    ys: NDArray[np.intp],
    xs: NDArray[np.intp],
    dx: NDArray[np.intp],
    dy: NDArray[np.intp],
    k: int = 4,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Mean of the first k filled offsets in (distance, angle) order: (values n x C, count n)."""
    d2 = dx * dx + dy * dy
    phi = np.mod(np.arctan2(dy, dx), 2 * np.pi)
    order = np.lexsort((np.round(phi, 9), d2))
    n, c = ys.size, val.shape[2]
    acc = np.zeros((n, c), np.float32)
    cnt = np.zeros(n, np.float32)
    for j in order:
        f, ok = _gather(filled, ys, xs, int(dx[j]), int(dy[j]))
        take = f & ok & (cnt < k)
        if not take.any():
            if (cnt >= k).all():
                break
            continue
        v, _ = _gather(val, ys, xs, int(dx[j]), int(dy[j]))
        acc[take] += v[take]
        cnt += take
    out = np.zeros((n, c), np.float32)
    ok = cnt > 0
    out[ok] = acc[ok] / cnt[ok][:, None]
    return out, cnt


def interpolate_4nn(
    raw: NDArray[Any],
    filled: NDArray[np.bool_],
    *,
    window: int = 7,
    max_window: int = 63,
) -> NDArray[Any]:
    """The 4-nearest-neighbour baseline of Fig. 3.6(c) ("4NN with 7x7 window size").

    An unfilled pixel takes the plain mean of the 4 filled pixels of its n x n window
    nearest to it (Euclidean distance; equal distances ordered by direction angle
    phi = atan2(dy, dx) in [0, 2 pi)); fewer than 4 in the window: the mean of those
    present; none: the window grows as in interpolate_two_layered.

    Args/Returns: as interpolate_two_layered.
    """
    val, _ = _check(raw, filled)
    _check_window(window)
    _check_window(max_window, "max_window")
    ys, xs = np.nonzero(~filled)
    dx, dy = window_offsets(window)
    vals, cnt = _knn_ring(val, filled, ys, xs, dx, dy)
    _grow(val, filled, ys, xs, vals, cnt, window, max(window, max_window), _knn_ring)
    return _finish(raw, ys, xs, vals)


@dataclass(frozen=True)
class EdgePairs:
    """Unfilled pixels found on an edge line (sec. 3.2.2 (2)) and their best pair.

    ys, xs: the on-edge unfilled pixels (row, column), shape (n,).
    a, b: offsets (dx, dy) in pixels from each pixel to its chosen support pair, (n, 2).
    theta_deg: their span angle theta_m in degrees, (n,).
    """

    ys: NDArray[np.intp]
    xs: NDArray[np.intp]
    a: NDArray[np.intp]
    b: NDArray[np.intp]
    theta_deg: NDArray[np.float64]


def _candidate_pairs(
    window: int, theta_t_deg: float
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    """Offset-index pairs (ia, ib) in opposite closed wedges with theta_m >= theta_t.

    Sorted by preference: theta_m closest to 180 degrees first, then the smaller
    d_a + d_b, then window order. Returns (ia, ib, theta_deg).
    """
    dx, dy = window_offsets(window)
    closed = _closed_wedges(dx, dy)
    seen: set[tuple[int, int]] = set()
    rows: list[tuple[float, float, int, int]] = []
    for w in range(4):
        for ia in np.flatnonzero(closed[w]):
            for ib in np.flatnonzero(closed[w + 4]):
                key = (int(min(ia, ib)), int(max(ia, ib)))
                if key in seen:
                    continue
                seen.add(key)
                va = (float(dx[ia]), float(dy[ia]))
                vb = (float(dx[ib]), float(dy[ib]))
                la, lb = math.hypot(*va), math.hypot(*vb)
                cosv = (va[0] * vb[0] + va[1] * vb[1]) / (la * lb)
                theta = math.degrees(math.acos(max(-1.0, min(1.0, cosv))))
                if theta >= theta_t_deg - 1e-9:
                    rows.append((-round(theta, 9), round(la + lb, 9), int(ia), int(ib)))
    rows.sort()
    ia_arr = np.array([r[2] for r in rows], np.intp)
    ib_arr = np.array([r[3] for r in rows], np.intp)
    th = np.array([-r[0] for r in rows], np.float64)
    return ia_arr, ib_arr, th


def find_on_edge_pairs(
    filled: NDArray[np.bool_],
    edges: NDArray[np.float32],
    *,
    e_t: float = 0.35,
    theta_t_deg: float = 120.0,
    window: int = 7,
) -> EdgePairs:
    """Local edge analysis of sec. 3.2.2 (2): which unfilled pixels lie on an edge line.

    Support pixels on the unwarped edge map are the filled pixels with edge value
    >= e_t. An unfilled pixel is on an edge line if two of them, P_k and P_l in
    opposite sub-regions of its window, span an angle theta_m >= theta_t; among all
    such candidate pairs the one with theta_m closest to 180 degrees is kept (ties:
    the nearer pair by d_a + d_b).

    Args:
        filled: H x W bool.
        edges: H x W float, the unwarped edge-value image (read at filled pixels only).
        e_t: edge threshold in [0, 1]; theta_t_deg: span-angle threshold in degrees.
        window: window size n (odd).
    """
    filled = np.asarray(filled)
    edges = np.asarray(edges)
    if filled.dtype != np.bool_:
        raise ValueError(f"filled must be a bool array, got {filled.dtype}")
    if edges.shape != filled.shape:
        raise ValueError(f"edges has shape {edges.shape}, filled has {filled.shape}: must match")
    _check_window(window)
    on = (filled & (edges >= e_t)).astype(np.uint8)
    dx, dy = window_offsets(window)
    r = window // 2
    closed = _closed_wedges(dx, dy)
    has: list[NDArray[Any]] = []
    for w in range(8):
        se = np.zeros((window, window), np.uint8)
        se[dy[closed[w]] + r, dx[closed[w]] + r] = 1
        has.append(cv2.dilate(on, se, anchor=(r, r), borderType=cv2.BORDER_CONSTANT, borderValue=0))
    cand = np.bitwise_and(has[0], has[4])
    for w in range(1, 4):
        cand |= np.bitwise_and(has[w], has[w + 4])
    cand &= (~filled).astype(np.uint8)
    ys, xs = np.nonzero(cand)
    empty = np.zeros((0, 2), np.intp)
    if ys.size == 0:
        return EdgePairs(ys, xs, empty, empty, np.zeros(0))
    h, w_ = filled.shape
    pad = np.zeros((h + 2 * r, w_ + 2 * r), np.bool_)
    pad[r : r + h, r : r + w_] = on.astype(np.bool_)
    base = (ys + r) * (w_ + 2 * r) + (xs + r)
    flat = pad.ravel()
    bits = np.stack([flat[base + int(dy[j]) * (w_ + 2 * r) + int(dx[j])] for j in range(dx.size)])
    ia, ib, th = _candidate_pairs(window, theta_t_deg)
    best = np.full(ys.size, -1, np.intp)
    free = np.ones(ys.size, np.bool_)
    for p in range(ia.size):
        v = bits[ia[p]] & bits[ib[p]]
        v &= free
        if v.any():
            np.copyto(best, p, where=v)
            free ^= v
            if not free.any():
                break
    keep = best >= 0
    bp = best[keep]
    a = np.stack([dx[ia[bp]], dy[ia[bp]]], axis=1)
    b = np.stack([dx[ib[bp]], dy[ib[bp]]], axis=1)
    return EdgePairs(ys[keep], xs[keep], a, b, th[bp])


def interpolate_edge_preserving(
    raw: NDArray[Any],
    filled: NDArray[np.bool_],
    edges: NDArray[np.float32],
    *,
    e_t: float = 0.35,
    theta_t_deg: float = 120.0,
    window: int = 7,
    max_window: int = 63,
) -> NDArray[Any]:
    """Edge-preserving 8-directional two-layered weighting interpolation (sec. 3.2.2).

    On-edge unfilled pixels (find_on_edge_pairs) take eq. 3.9,
    I_u = (I_a / d_a + I_b / d_b) / (1 / d_a + 1 / d_b), from their best pair; all
    others take the two-layered value (interpolate_two_layered, same window).

    Args:
        raw, filled: as interpolate_two_layered.
        edges: H x W float, the edge-value image of the omni-image (sobel_edge_value)
            unwarped the same way as raw; only its filled pixels are read.
        e_t: edge-value threshold (0.35 as in Fig. 3.6); theta_t_deg: span-angle
            threshold in degrees (120); window: n of the n x n window (7).
    Returns:
        As interpolate_two_layered.
    Example:
        The same pixels on an edge line: eq. 3.9 weighs the nearer support more.

        >>> raw = np.array([[10, 0, 0, 40]], np.uint8)
        >>> interpolate_edge_preserving(raw, raw > 0, np.ones(raw.shape, np.float32))
        array([[10, 20, 30, 40]], dtype=uint8)
    """
    val, _ = _check(raw, filled)
    _check_window(window)
    _check_window(max_window, "max_window")
    if np.asarray(edges).shape != filled.shape:
        raise ValueError(
            f"edges has shape {np.asarray(edges).shape}, filled has {filled.shape}: must match"
        )
    ys, xs = np.nonzero(~filled)
    vals = _two_layered_values(val, filled, ys, xs, window, max(window, max_window))
    pairs = find_on_edge_pairs(filled, edges, e_t=e_t, theta_t_deg=theta_t_deg, window=window)
    if pairs.ys.size:
        w = filled.shape[1]
        va = val[pairs.ys + pairs.a[:, 1], pairs.xs + pairs.a[:, 0]]
        vb = val[pairs.ys + pairs.b[:, 1], pairs.xs + pairs.b[:, 0]]
        ia = (1.0 / np.hypot(pairs.a[:, 0], pairs.a[:, 1])).astype(np.float32)[:, None]
        ib = (1.0 / np.hypot(pairs.b[:, 0], pairs.b[:, 1])).astype(np.float32)[:, None]
        pos = np.searchsorted(ys * w + xs, pairs.ys * w + pairs.xs)
        vals[pos] = (ia * va + ib * vb) / (ia + ib)
    return _finish(raw, ys, xs, vals)


# --------------------------------------------------------- synthetic hole mask


def synthetic_unfilled_mask(
    shape: tuple[int, int],
    *,
    magnification: tuple[float, float] = (1.0, 1.8),
    angle_deg: float = 7.0,
    wobble_px: float = 0.35,
) -> NDArray[np.bool_]:
    """A filled mask like back-projection gives: True where a scattered sample landed.

    A unit lattice of omni-image samples, rotated by angle_deg, is spread over the
    H x W view with a local magnification growing smoothly from magnification[0] at
    the left edge to magnification[1] at the right (both axes; the vertical spread
    grows half as fast), with a sinusoidal wobble of wobble_px pixels; each sample
    fills the pixel it rounds to. Holes: irregular, few on the left, dense on the
    right (~30 % overall with the defaults). Deterministic.
    """
    h, w = shape
    m0, m1 = magnification
    # x' = w * g(t), t = u / w, g'(t) = m0 + (m1 - m0) t  ->  g = m0 t + (m1 - m0) t^2 / 2
    a = math.radians(angle_deg)
    # lattice (i, j) -> (u, v) = R(a) (i, j); cover u in [0, w], v in [0, h] (+ margin)
    cu = np.array([0.0, w, 0.0, w]) + np.array([-2, 2, -2, 2])
    cv = np.array([0.0, 0.0, h, h]) + np.array([-2, -2, 2, 2])
    ci = math.cos(a) * cu + math.sin(a) * cv
    cj = -math.sin(a) * cu + math.cos(a) * cv
    j, i = np.mgrid[
        math.floor(cj.min()) : math.ceil(cj.max()) + 1,
        math.floor(ci.min()) : math.ceil(ci.max()) + 1,
    ].astype(np.float64)
    u = math.cos(a) * i - math.sin(a) * j
    v = math.sin(a) * i + math.cos(a) * j
    t = u / w
    xg = w * (m0 * t + (m1 - m0) * t * t / 2.0)
    sy = 1.0 + 0.5 * ((m0 - 1.0) + (m1 - m0) * np.clip(xg / w, 0.0, 1.0))
    yg = (v - h / 2.0) * sy + h / 2.0
    xg = xg + wobble_px * np.sin(v * 0.37) + wobble_px * np.sin(u * 0.23)
    yg = yg + wobble_px * np.cos(u * 0.29)
    xi, yi = np.rint(xg).astype(np.intp), np.rint(yg).astype(np.intp)
    ok = (u >= 0) & (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
    mask = np.zeros((h, w), np.bool_)
    mask[yi[ok], xi[ok]] = True
    return mask
