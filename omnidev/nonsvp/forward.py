"""Forward projection of the non-SVP camera: world point -> pixel, solved numerically.

A misaligned camera has no closed form (the rays of its pixels do not share a
viewpoint), so :func:`project` finds, for each scene point X, the mirror point
M where the light from X reflects into the lens centre O: the stationary point
of the path length L(M) = |M - O| + |M - X| over the mirror surface (Fermat;
for a convex mirror it is a minimum). M is parametrised by its (x, y) in O_m,
z = -c + b sqrt(1 + r^2 / a^2) (eq. 2.19), and found by Newton's method on
grad L = 0 with the analytic Hessian, vectorized over all points, started from
the aligned (SVP) mirror point where the segment from X to the focus O_m
meets the mirror. M is then imaged through the lens (eqs. 2.5-2.9).

:func:`project_svp_eq21` is eq. 2.1, the aligned camera's closed form, used as
the SVP-assumption baseline and as the check of the model's SVP limit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from omnidev.nonsvp.model import Lens, Mirror, NonSvpCamera, ideal_to_pixel

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = ["project", "project_svp_eq21", "svp_mirror_point"]

_MAX_ITER = 40
_TOL = 1e-7  # mm, Newton step size after which a point counts as converged
_CHUNK = 16384  # points solved together
_MAX_STEP = 4.0  # mm, cap on one Newton step


def _newton(
    mir: Mirror,
    o: FloatArray,
    targets: FloatArray,
    x: FloatArray,
    y: FloatArray,
    ok: BoolArray,
    finite: bool,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Newton on grad L = 0 for one chunk: mirror (x, y) of the reflection points, converged mask.

    ``targets``: scene points (finite) or unit directions (not finite), O_m.
    A step shorter than ``_TOL`` ends a point's iteration (Newton converges
    quadratically: the error left after such a step is ~ step^2 / (curvature
    radius), < 1e-13 mm here); steps are capped at ``_MAX_STEP``, and where the
    Hessian is not positive definite a gradient step is taken instead.
    """
    a2, b, c = mir.a**2, mir.b, mir.c
    x = x.copy()
    y = y.copy()
    done = ~ok
    conv = np.zeros(len(x), dtype=np.bool_)
    tx, ty, tz = targets[:, 0], targets[:, 1], targets[:, 2]
    for _ in range(_MAX_ITER):
        s = np.sqrt(1.0 + (x * x + y * y) / a2)
        z = b * s - c
        k = b / (a2 * s)
        gx, gy = k * x, k * y
        kk = k / (a2 * s * s)
        # e1: unit vector from the lens centre to M; a1, c1: its dot with M_x, M_y
        p1x, p1y, p1z = x - o[0], y - o[1], z - o[2]
        r1 = np.sqrt(p1x * p1x + p1y * p1y + p1z * p1z)
        e1z = p1z / r1
        a1 = (p1x + gx * p1z) / r1
        c1 = (p1y + gy * p1z) / r1
        mxx = 1.0 + gx * gx
        mxy = gx * gy
        myy = 1.0 + gy * gy
        hxx = (mxx - a1 * a1) / r1
        hxy = (mxy - a1 * c1) / r1
        hyy = (myy - c1 * c1) / r1
        if finite:  # e2: unit vector from X to M
            p2x, p2y, p2z = x - tx, y - ty, z - tz
            r2 = np.sqrt(p2x * p2x + p2y * p2y + p2z * p2z)
            e2z = p2z / r2
            a2_ = (p2x + gx * p2z) / r2
            c2_ = (p2y + gy * p2z) / r2
            hxx += (mxx - a2_ * a2_) / r2
            hxy += (mxy - a2_ * c2_) / r2
            hyy += (myy - c2_ * c2_) / r2
        else:  # |M - X| -> const - M . v for X at infinity along v
            e2z = -tz
            a2_ = -(tx + gx * tz)
            c2_ = -(ty + gy * tz)
        sz = e1z + e2z
        hxx += sz * (k - kk * x * x)
        hxy -= sz * kk * x * y
        hyy += sz * (k - kk * y * y)
        grx = a1 + a2_
        gry = c1 + c2_
        det = hxx * hyy - hxy * hxy
        good = (det > 0.0) & (hxx > 0.0)
        safe = np.where(good, det, 1.0)
        dx = np.where(good, -(hyy * grx - hxy * gry) / safe, -0.5 * r1 * grx)
        dy = np.where(good, -(hxx * gry - hxy * grx) / safe, -0.5 * r1 * gry)
        step = np.hypot(dx, dy)
        scale = np.minimum(1.0, _MAX_STEP / np.maximum(step, 1e-300))
        move = ~done
        x = np.where(move, x + dx * scale, x)
        y = np.where(move, y + dy * scale, y)
        fin = move & good & (step < _TOL)
        conv |= fin
        done |= fin
        if bool(np.all(done)):
            break
    return x, y, conv


def _points3(x: ArrayLike) -> FloatArray:
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 1 and arr.shape[0] == 3:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"X: expected shape (N, 3) points in O_m, got {arr.shape}")
    return arr


def svp_mirror_point(mirror: Mirror, directions: ArrayLike) -> tuple[FloatArray, BoolArray]:
    """Where rays from the focus O_m along ``directions`` (N, 3) meet the mirror, mm in O_m.

    For the sheet of eq. 2.19, |P - (0, 0, -2c)| - |P| = 2b gives the focal
    polar form |P| = a^2 / (b - c v_z) for unit v; valid where v_z < b / c.
    """
    v = _points3(directions)
    v = v / np.linalg.norm(v, axis=1, keepdims=True)
    den = mirror.b - mirror.c * v[:, 2]
    ok = den > 0.0
    rho = mirror.a**2 / np.where(ok, den, 1.0)
    return np.asarray(v * rho[:, None], dtype=np.float64), np.asarray(ok, dtype=np.bool_)


def project(
    cam: NonSvpCamera, X: ArrayLike, *, finite: bool = True
) -> tuple[FloatArray, BoolArray]:
    """(N, 3) scene points in O_m (mm) -> (N, 2) pixels and an (N,) mask.

    With ``finite=False`` the rows of X are directions (from O_m towards a
    point at infinity) instead of points. valid is False where the mirror
    cannot show X to the lens: no mirror point inside the rim reflects X into
    the lens (X beyond the rim's or the asymptote's reach, inside or behind the
    mirror), the lens does not face the mirror point, eq. 2.8 cannot be
    inverted there, or Newton did not converge. The pixel may lie outside the
    image frame; check against ``cam.image_size`` if that matters. Invalid
    rows hold NaN. Points are solved in chunks of ``_CHUNK`` so that the work
    stays in the CPU cache.
    """
    x_pts = _points3(X)
    n = len(x_pts)
    px = np.full((n, 2), np.nan)
    valid = np.zeros(n, dtype=np.bool_)
    for lo in range(0, n, _CHUNK):
        sl = slice(lo, min(n, lo + _CHUNK))
        px[sl], valid[sl] = _project_chunk(cam, x_pts[sl], finite)
    return px, valid


def _project_chunk(
    cam: NonSvpCamera, pts: FloatArray, finite: bool
) -> tuple[FloatArray, BoolArray]:
    mir = cam.mirror
    a2, b2, b, c = mir.a**2, mir.b**2, mir.b, mir.c
    o = cam.center_in_mirror()
    tx, ty, tz = pts[:, 0].copy(), pts[:, 1].copy(), pts[:, 2].copy()
    nx = np.sqrt(tx * tx + ty * ty + tz * tz)
    ok = nx > 0.0
    inv = 1.0 / np.where(ok, nx, 1.0)
    vx, vy, vz = tx * inv, ty * inv, tz * inv
    # start: the aligned camera's mirror point, where X -> O_m meets the mirror
    den = b - c * vz
    ok &= den > 0.0
    rho = a2 / np.where(ok, den, 1.0)
    x0, y0 = vx * rho, vy * rho
    if finite:  # points inside the mirror body are not seen
        ok &= tz + c < b * np.sqrt(1.0 + (tx * tx + ty * ty) / a2)
        targets = np.column_stack([tx, ty, tz])
    else:
        targets = np.column_stack([vx, vy, vz])
    targets[~ok] = (0.0, 0.0, -1.0)
    x, y, conv = _newton(mir, o, targets, x0, y0, ok, finite)
    z = b * np.sqrt(1.0 + (x * x + y * y) / a2) - c
    valid = ok & conv & (z <= mir.d)
    # unnormalised outward normal (x / a^2, y / a^2, -(z + c) / b^2): lens and X in front
    gnx, gny, gnz = x / a2, y / a2, -(z + c) / b2
    valid &= gnx * (o[0] - x) + gny * (o[1] - y) + gnz * (o[2] - z) > 0.0
    if finite:
        valid &= gnx * (tx - x) + gny * (ty - y) + gnz * (tz - z) > 0.0
    else:
        valid &= gnx * vx + gny * vy + gnz * vz > 0.0
    r = cam.pose.R()  # camera frame: x_c = R (M - O) (eqs. 2.13-2.16 inverted)
    dx, dy, dz = x - o[0], y - o[1], z - o[2]
    xc = r[0, 0] * dx + r[0, 1] * dy + r[0, 2] * dz
    yc = r[1, 0] * dx + r[1, 1] * dy + r[1, 2] * dz
    zc = r[2, 0] * dx + r[2, 1] * dy + r[2, 2] * dz
    valid &= zc > 0.0
    fz = cam.lens.f / np.where(zc > 0.0, zc, 1.0)
    ideal = np.column_stack([xc * fz, yc * fz])
    if cam.lens.kappa == 0.0:
        (sx, sy), (cx, cy) = cam.lens.scale, cam.lens.principal_point
        out = np.column_stack([ideal[:, 0] * sx + cx, ideal[:, 1] * sy + cy])
    else:
        out, ok_lens = ideal_to_pixel(cam.lens, ideal)
        valid &= ok_lens
    out[~valid] = np.nan
    return out, valid


def project_svp_eq21(mirror: Mirror, lens: Lens, X: ArrayLike) -> tuple[FloatArray, BoolArray]:
    """Eq. 2.1: (N, 3) points in O_m (mm) -> (N, 2) pixels of the aligned (SVP) camera.

    u = f (b^2 - c^2) x / ((b^2 + c^2) z - 2 b c |X|), v likewise with y (ideal
    mm, then eqs. 2.8-2.9 through ``lens``). valid: the segment from X to O_m
    meets the mirror inside its rim (v_z <= d / |(m, d)| in elevation terms)
    and eq. 2.8 inverts; this is the camera model the SVP-assumption unwarp
    uses, whatever the real pose.
    """
    p = _points3(X)
    b, c = mirror.b, mirror.c
    nx = np.linalg.norm(p, axis=1)
    den = (b * b + c * c) * p[:, 2] - 2.0 * b * c * nx
    safe = np.where(den != 0.0, den, 1.0)
    ideal = lens.f * (b * b - c * c) * p[:, :2] / safe[:, None]
    m, ok = svp_mirror_point(mirror, np.where(nx[:, None] > 0.0, p, [[0.0, 0.0, -1.0]]))
    ok &= (nx > 0.0) & (den != 0.0) & (m[:, 2] <= mirror.d)
    px, ok_lens = ideal_to_pixel(lens, ideal)
    ok &= ok_lens
    px[~ok] = np.nan
    return px, np.asarray(ok, dtype=np.bool_)
