"""Ring-pattern calibration of the camera's pose against the mirror (dissertation sec. 2.3.2-2.3.3).

Steps (each a function here):

1. :func:`detect_ring_points`: the 16 calibration points of the ring of
   :mod:`omnidev.nonsvp.ring_pattern` in an image of it (sub-pixel, labelled by mark).
   Or :func:`parse_points_csv` for points measured elsewhere.
2. :func:`calibrate_tsai`: Tsai's single-view coplanar calibration (R. Tsai 1987, the
   method the text cites for eqs. 2.11-2.12) with the focal length f known: the linear
   radial-alignment stage for R, T_x, T_y; then T_z and kappa by nonlinear least
   squares (``refine="tsai"``, Tsai's own second stage); ``refine="full"`` further
   refines all seven parameters on the reprojection error (as Willson's reference
   implementation of Tsai's method does).
3. :func:`solvepnp_pose`: the same pose from ``cv2.solvePnP`` for a cross-check.
4. :func:`pose_wrt_mirror`: the conversion of sec. 2.3.3 (eqs. 2.13-2.16) to the
   camera's pose relative to the mirror, literally, and the exact inverse beside it.

Frames (mm, rad). Base frame (x_b, y_b, z_b): origin at the centre of the mirror's
base circle, z_b = 0 on the base plane (the ring's plane), z_b pointing from the
camera towards the mirror base. Camera frame (x, y, z): origin at the lens centre,
z along the optical axis towards the mirror, x along the image's columns, y along its
rows (down). Tsai's result is eq. 2.4, ``x_cam = R_t x_b + T_t``; the model's
:class:`Pose` is eq. 2.13, ``x_b = R^T x_cam - T``, so R = R_t and T = R_t^T T_t, with
R = Rz(tilt) Ry(yaw) Rx(pitch).
Pixels (u_f, v_f): centre of the top-left pixel = (0, 0). Distorted sensor
coordinates (u_d, v_d) in mm on the sensor (eq. 2.11); ideal ones (u, v) from the lens
model (eq. 2.8); kappa in mm^-2 in the lens's sign convention.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field, replace
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.nonsvp.model import (
    Lens,
    Pose,
    angles_from_rotation,
    base_to_camera,
    ideal_to_pixel,
    pixel_to_distorted,
    rotation_pitch_yaw_tilt,
)
from omnidev.screencal.lsq import levenberg_marquardt

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
MIN_POINTS = 5
"""Tsai's coplanar linear stage has five unknowns: at least five points are needed."""
_PREFIX = "ring calibration"

# --------------------------------------------------------------------------- lens


def sensor_from_pixels(lens: Lens, pixels: FloatArray) -> FloatArray:
    """(n, 2) pixels (u_f, v_f) -> (n, 2) distorted sensor coordinates (u_d, v_d), mm (eq. 2.11)."""
    return pixel_to_distorted(lens, pixels)


def _undistort(ud: FloatArray, k_tsai: float) -> FloatArray:
    """Eq. 2.12's left side: u_d (1 + k r_d^2) with Tsai's kappa (= -kappa of eq. 2.8)."""
    r2 = (ud**2).sum(axis=-1, keepdims=True)
    return np.asarray(ud * (1.0 + k_tsai * r2), np.float64)


def project_plane_points(lens: Lens, pose: Pose, points_b: FloatArray) -> FloatArray:
    """(n, 3) base-frame points (mm) -> (n, 2) pixels through the model's pose (eq. 2.13
    inverted: x_c = R (x_b + T)), eq. 2.5, eq. 2.8 inverted and eq. 2.9. Points behind
    the camera or beyond the distortion's fold -> NaN."""
    xc = base_to_camera(pose, points_b)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(xc[:, 2] > 0, xc[:, 2], np.nan)
        ideal = lens.f * xc[:, :2] / z[:, None]
    px, ok = ideal_to_pixel(lens, np.nan_to_num(ideal))
    return np.where((ok & np.isfinite(z))[:, None], px, np.nan)


# --------------------------------------------------------------------------- Tsai


@dataclass(frozen=True)
class RingCalibration:
    """Result of :func:`calibrate_tsai`.

    ``R_t``, ``T_t``: Tsai's extrinsics of eq. 2.4, ``x_cam = R_t x_b + T_t`` (mm).
    ``pose``: the camera's pose relative to the mirror base in the model's terms
    (sec. 2.3.3 done exactly: :meth:`Pose.from_tsai`, see :func:`pose_wrt_mirror`).
    ``kappa``: radial distortion of eq. 2.8 (1/mm^2; eq. 2.12's kappa is its negative).
    ``residuals_px``: (n, 2) measured minus reprojected pixels. ``indices``: mark number
    of each point. ``stage1``: (R_t, T_t) from Tsai's linear stage alone (T_z from its
    linear equation with f fixed, kappa = 0). ``method``: the refinement used.
    """

    R_t: FloatArray
    T_t: FloatArray
    kappa: float
    pose: Pose
    residuals_px: FloatArray
    indices: IntArray
    method: str
    stage1: tuple[FloatArray, FloatArray]
    notes: tuple[str, ...] = field(default=())

    @property
    def rms_px(self) -> float:
        """Root-mean-square reprojection error (px)."""
        return float(np.sqrt((self.residuals_px**2).sum(axis=1).mean()))


def _check_points(pixels: FloatArray, plane_mm: FloatArray, what: str) -> tuple[FloatArray, ...]:
    uv = np.asarray(pixels, np.float64)
    xy = np.asarray(plane_mm, np.float64)
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise CalibrationError(f"{_PREFIX}: pixels must be (n, 2), got {uv.shape}")
    if xy.ndim != 2 or xy.shape[1] not in (2, 3) or len(xy) != len(uv):
        raise CalibrationError(
            f"{_PREFIX}: plane points must be (n, 2|3) like the pixels, got {xy.shape}"
        )
    if xy.shape[1] == 3 and np.any(np.abs(xy[:, 2]) > 1e-9):
        raise CalibrationError(f"{_PREFIX}: plane points must have z_b = 0 (coplanar method)")
    if len(uv) < MIN_POINTS:
        raise CalibrationError(
            f"{_PREFIX}: {len(uv)} calibration points {what}; Tsai's coplanar calibration "
            f"needs at least {MIN_POINTS}"
        )
    if not (np.all(np.isfinite(uv)) and np.all(np.isfinite(xy))):
        raise CalibrationError(f"{_PREFIX}: non-finite calibration point coordinates")
    _check_spread(uv, "image points (px)", 1e-3)
    _check_spread(xy[:, :2], "plane points (mm)", 1e-6)
    return uv, xy[:, :2]


def _check_spread(pts: FloatArray, what: str, tol: float) -> None:
    """Refuse points that cannot fix a pose: fewer than :data:`MIN_POINTS` distinct ones
    (``tol`` apart), or all on one line (the pose is then not unique, yet fits exactly)."""
    distinct = len(np.unique(np.round(pts / tol), axis=0))
    if distinct < MIN_POINTS:
        raise CalibrationError(
            f"{_PREFIX}: {distinct} distinct {what} among {len(pts)}; Tsai's coplanar "
            f"calibration needs at least {MIN_POINTS} (repeated rows?)"
        )
    sv = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    if sv[1] <= 1e-6 * sv[0]:
        raise CalibrationError(
            f"{_PREFIX}: the {what} all lie on one line; the pose needs points around the ring"
        )


def _nearest_rotation(m: FloatArray) -> FloatArray:
    u, _, vt = np.linalg.svd(m)
    if np.linalg.det(u @ vt) < 0:
        u[:, -1] *= -1
    return np.asarray(u @ vt, np.float64)


def _tsai_linear(ud: FloatArray, xy: FloatArray, f: float) -> list[tuple[FloatArray, FloatArray]]:
    """Tsai's stage 1 (coplanar case): the radial alignment constraint
    ``u_d (r21 x + r22 y + T_y) = v_d (r11 x + r12 y + T_x)`` solved linearly for
    (r11, r12, T_x, r21, r22) / T_y; |T_y| from the orthonormality of R's 2x2 block; the
    sign of T_y from the point farthest from the image centre; R's third column and row
    from orthonormality; then T_z from eq. 2.12 with kappa = 0 and f fixed.

    Returns both rotations of the sign ambiguity of (r13, r23) as (R_t, T_t) pairs,
    Tsai's pick first (the one whose linear estimate of f, made as in Tsai's paper, is
    positive).
    """
    X, Y = ud[:, 0], ud[:, 1]
    x, y = xy[:, 0], xy[:, 1]
    A = np.stack([Y * x, Y * y, Y, -X * x, -X * y], axis=1)
    a, *_ = np.linalg.lstsq(A, X, rcond=None)
    a1, a2, a3, a4, a5 = (float(v) for v in a)
    sr = a1**2 + a2**2 + a4**2 + a5**2
    det = a1 * a5 - a4 * a2
    if abs(det) > 1e-12 * sr:
        ty2 = (sr - math.sqrt(max(sr**2 - 4.0 * det**2, 0.0))) / (2.0 * det**2)
    else:  # a row or column of the 2x2 block vanishes (Tsai's special case)
        ty2 = 1.0 / max(a1**2 + a2**2, a4**2 + a5**2, a1**2 + a4**2, a2**2 + a5**2)
    ty = math.sqrt(ty2)
    far = int(np.argmax(X**2 + Y**2))
    xc = (a1 * x[far] + a2 * y[far] + a3) * ty
    yc = (a4 * x[far] + a5 * y[far] + 1.0) * ty
    if not (np.sign(xc) == np.sign(X[far]) and np.sign(yc) == np.sign(Y[far])):
        ty = -ty
    r11, r12, tx, r21, r22 = a1 * ty, a2 * ty, a3 * ty, a4 * ty, a5 * ty
    r13 = math.sqrt(max(1.0 - r11**2 - r12**2, 0.0))
    r23 = -math.copysign(1.0, r11 * r21 + r12 * r22) * math.sqrt(max(1.0 - r21**2 - r22**2, 0.0))
    out: list[tuple[FloatArray, FloatArray, float]] = []
    for sign in (1.0, -1.0):
        row1 = np.array([r11, r12, sign * r13])
        row2 = np.array([r21, r22, sign * r23])
        rot = _nearest_rotation(np.stack([row1, row2, np.cross(row1, row2)]))
        xi = rot[0, 0] * x + rot[0, 1] * y + tx
        yi = rot[1, 0] * x + rot[1, 1] * y + ty
        wi = rot[2, 0] * x + rot[2, 1] * y
        # linear form of eq. 2.12 with kappa = 0: f x_c - u_d T_z = u_d w (and for v)
        M = np.concatenate([np.stack([xi, -X], 1), np.stack([yi, -Y], 1)])
        rhs = np.concatenate([wi * X, wi * Y])
        sol, *_ = np.linalg.lstsq(M, rhs, rcond=None)
        d = np.concatenate([X, Y])
        tz = float(d @ (f * np.concatenate([xi, yi]) - rhs)) / float(d @ d)
        out.append((rot, np.array([tx, ty, tz]), float(sol[0])))
    out.sort(key=lambda c: c[2] <= 0)  # Tsai: flip (r13, r23) when the linear f is negative
    return [(rot, t) for rot, t, _ in out]


def _residuals(
    rot: FloatArray,
    t: FloatArray,
    k_tsai: float,
    ud: FloatArray,
    xy: FloatArray,
    f: float,
    sxy: FloatArray,
) -> FloatArray:
    """Eq. 2.12 residuals, ``u_d (1 + k r_d^2) - f x_c / z_c``, scaled to pixels by S_x, S_y."""
    xc = xy @ rot[:, :2].T + t
    pred = f * xc[:, :2] / xc[:, 2:3]
    return np.asarray(((_undistort(ud, k_tsai) - pred) * sxy).ravel(), np.float64)


def calibrate_tsai(
    pixels: FloatArray,
    plane_mm: FloatArray,
    lens: Lens,
    *,
    indices: IntArray | None = None,
    refine: Literal["tsai", "full"] = "full",
    estimate_kappa: bool = False,
) -> RingCalibration:
    """Tsai's single-view coplanar calibration with f known (eqs. 2.11-2.12).

    Args:
        pixels: (n, 2) calibration points in the image (u_f, v_f), px.
        plane_mm: (n, 2) or (n, 3) the same points in the base frame (mm, z_b = 0).
        lens: f, sensor size, image size and centre (eq. 2.10); its kappa is not used.
        indices: optional mark number of each point (kept in the result).
        refine: ``"tsai"`` = Tsai 1987: R, T_x, T_y from the linear stage, then T_z and
            kappa by Levenberg-Marquardt on eq. 2.12 (Tsai's second stage with f
            known); ``"full"`` = then pitch, yaw, tilt, T and kappa together on the
            same residuals (px), started from both signs of the linear stage's
            (r13, r23) ambiguity, the lower cost kept.
        estimate_kappa: True estimates kappa too (eq. 2.12). Off by default: the ring's
            points all lie near one image radius, where kappa r^2 is nearly a constant
            scale and trades against T_z (0.3 px of point noise then moves T by tens of
            mm); the dissertation's own result has kappa = 0.

    Returns:
        :class:`RingCalibration`.

    Raises CalibrationError with fewer than :data:`MIN_POINTS` points, on bad shapes,
    or when the result puts the base plane behind the camera.

    Example:
        >>> from omnidev.nonsvp.model import DISSERTATION_CAMERA as cam
        >>> from omnidev.nonsvp.ring_pattern import RingLayout
        >>> pts = RingLayout(cam.mirror.m).calibration_points_mm()
        >>> cal = calibrate_tsai(project_plane_points(cam.lens, cam.pose, pts), pts, cam.lens)
        >>> np.round(cal.pose.T, 6).tolist(), round(cal.pose.yaw, 9)
        ([-2.99, 0.96, 88.67], 0.035)
    """
    uv, xy = _check_points(pixels, plane_mm, "given")
    ud = pixel_to_distorted(lens, uv)
    f = float(lens.f)
    sxy = np.asarray(lens.scale, np.float64)
    idx = np.arange(len(uv)) if indices is None else np.asarray(indices, np.int64)
    candidates = _tsai_linear(ud, xy, f)
    results: list[tuple[float, FloatArray, FloatArray, float]] = []
    for n_cand, (rot, t) in enumerate(candidates):
        if n_cand > 0 and refine == "tsai":
            break

        def res2(p: FloatArray, rot: FloatArray = rot, t: FloatArray = t) -> FloatArray:
            k = float(p[1]) if estimate_kappa else 0.0
            return _residuals(rot, np.array([t[0], t[1], p[0]]), k, ud, xy, f, sxy)

        p2 = levenberg_marquardt(res2, np.array([t[2], 0.0]), iterations=200)
        k_tsai = float(p2[1]) if estimate_kappa else 0.0
        t2 = np.array([t[0], t[1], float(p2[0])])
        if refine == "tsai":
            results.append((float((res2(p2) ** 2).sum()), rot, t2, k_tsai))
            break

        def res7(p: FloatArray) -> FloatArray:
            r = rotation_pitch_yaw_tilt(float(p[0]), float(p[1]), float(p[2]))
            k = float(p[6]) if estimate_kappa else 0.0
            return _residuals(r, p[3:6], k, ud, xy, f, sxy)

        p7 = np.array([*angles_from_rotation(rot), *t2, k_tsai])
        p7 = levenberg_marquardt(res7, p7, iterations=400, rel_step=1e-7)
        rot7 = rotation_pitch_yaw_tilt(float(p7[0]), float(p7[1]), float(p7[2]))
        k7 = float(p7[6]) if estimate_kappa else 0.0
        results.append((float((res7(p7) ** 2).sum()), rot7, np.asarray(p7[3:6]), k7))
    results.sort(key=lambda c: c[0])
    _, rot, t, k_tsai = results[0]
    if t[2] <= 0:
        raise CalibrationError(f"{_PREFIX}: the solution puts the base plane behind the camera")
    notes: list[str] = []
    if len(results) > 1 and results[1][0] < 4.0 * max(results[0][0], 1e-20):
        notes.append(
            "the two tilt-sign solutions fit about equally well (near-frontal view); "
            f"costs {results[0][0]:.3g} and {results[1][0]:.3g} px^2"
        )
    pose = pose_wrt_mirror(rot, t)
    lens_k = replace(lens, kappa=-k_tsai)
    pred = project_plane_points(lens_k, pose, np.c_[xy, np.zeros(len(xy))])
    stage1 = candidates[0]
    return RingCalibration(
        R_t=rot,
        T_t=np.asarray(t, np.float64),
        kappa=-k_tsai,
        pose=pose,
        residuals_px=uv - pred,
        indices=idx,
        method=refine,
        stage1=stage1,
        notes=tuple(notes),
    )


def pose_wrt_mirror(
    R_t: FloatArray, T_t: FloatArray, *, method: Literal["exact", "dissertation"] = "exact"
) -> Pose:
    """Sec. 2.3.3: the camera's pose relative to the mirror base from Tsai's R_t, T_t.

    ``"exact"``: the inverse of eq. 2.4 written in eq. 2.13's form, which is how
    :class:`Pose` is defined (``x_b = R^T x_c - T``): R = R_t, T = R_t^T T_t
    (:meth:`Pose.from_tsai`). ``"dissertation"``: the text as printed: T = T_t as it
    is, the angles those of R_t. The two differ by (R_t^T - I) T_t: about 3.1 mm in x
    at the dissertation's pose (yaw 0.035 rad x T_z 88.67 mm). The camera's own
    angles (pitch_c, yaw_c, tilt_c of Fig. 2.6) are minus the pose's; its centre in
    the mirror frame is ``NonSvpCamera.center_in_mirror()`` (eq. 2.16).
    """
    r = np.asarray(R_t, np.float64)
    t = np.asarray(T_t, np.float64).ravel()
    if method == "exact":
        return Pose.from_tsai(r, t)
    if method == "dissertation":
        pitch, yaw, tilt = angles_from_rotation(r)
        return Pose(pitch, yaw, tilt, (float(t[0]), float(t[1]), float(t[2])))
    raise CalibrationError(f"{_PREFIX}: unknown conversion {method!r}")


# --------------------------------------------------------------------------- cross-check


@dataclass(frozen=True)
class PnpCheck:
    """``cv2.solvePnP`` on the same points: its R_t, T_t (eq. 2.4) and, when given a
    calibration, the difference: rotation angle of R_tsai^T R_pnp (mrad) and
    |T_tsai - T_pnp| (mm)."""

    R_t: FloatArray
    T_t: FloatArray
    rotation_diff_mrad: float
    translation_diff_mm: float


def solvepnp_pose(
    pixels: FloatArray,
    plane_mm: FloatArray,
    lens: Lens,
    calibration: RingCalibration | None = None,
) -> PnpCheck:
    """Pose of the base plane by ``cv2.solvePnP`` (SOLVEPNP_ITERATIVE), K from eq. 2.10.

    The points are first undistorted with the calibration's kappa (or the lens's when
    ``calibration`` is None), so both methods see the same ideal image points.
    """
    uv, xy = _check_points(pixels, plane_mm, "given")
    kappa = calibration.kappa if calibration is not None else lens.kappa
    ideal = _undistort(pixel_to_distorted(lens, uv), -kappa)
    (sx, sy), (cx, cy) = lens.scale, lens.principal_point
    K = np.array([[lens.f * sx, 0.0, cx], [0.0, lens.f * sy, cy], [0.0, 0.0, 1.0]])
    img = np.c_[ideal[:, 0] * sx + cx, ideal[:, 1] * sy + cy]
    obj = np.c_[xy, np.zeros(len(xy))]
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, None, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise CalibrationError(f"{_PREFIX}: cv2.solvePnP found no pose")
    rot = np.asarray(cv2.Rodrigues(rvec)[0], np.float64)
    t = np.asarray(tvec, np.float64).ravel()
    rdiff = tdiff = float("nan")
    if calibration is not None:
        rel = calibration.R_t.T @ rot
        rdiff = 1e3 * float(np.arccos(np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0)))
        tdiff = float(np.linalg.norm(calibration.T_t - t))
    return PnpCheck(rot, t, rdiff, tdiff)


# --------------------------------------------------------------------------- points input


def parse_points_csv(text: str, *, source: str) -> tuple[FloatArray, FloatArray]:
    """Calibration points from CSV text: one point per row, ``u, v, X, Y`` (pixels, then
    base-plane mm); an optional header row whose first cell is not a number; ``#``
    comment lines and blank lines skipped. Errors name ``source`` and the row (1-based).

    Returns (pixels (n, 2), plane points (n, 3) with z_b = 0).

    Example:
        >>> uv, xy = parse_points_csv("u,v,X,Y\\n10,20,30,0\\n", source="pts.csv")
        >>> uv.tolist(), xy.tolist()
        ([[10.0, 20.0]], [[30.0, 0.0, 0.0]])
    """
    uv: list[tuple[float, float]] = []
    xy: list[tuple[float, float]] = []
    try:
        rows = list(csv.reader(io.StringIO(text)))
    except csv.Error as exc:
        raise CalibrationError(f"{source}: not a CSV file ({exc})") from None
    for row_no, row in enumerate(rows, start=1):
        cells = [c.strip() for c in row]
        if not cells or all(not c for c in cells) or cells[0].startswith("#"):
            continue
        if row_no == 1 and not _is_number(cells[0]):
            continue
        if len(cells) != 4:
            raise CalibrationError(
                f"{source}: row {row_no}: expected 4 values u, v, X, Y, got {len(cells)}"
            )
        try:
            vals = [float(c) for c in cells]
        except ValueError:
            raise CalibrationError(f"{source}: row {row_no}: not a number in {row!r}") from None
        if not all(math.isfinite(v) for v in vals):
            raise CalibrationError(f"{source}: row {row_no}: non-finite value in {row!r}")
        if not all(abs(v) <= 1e6 for v in vals):
            raise CalibrationError(f"{source}: row {row_no}: a value beyond 1e6 in {row!r}")
        uv.append((vals[0], vals[1]))
        xy.append((vals[2], vals[3]))
    if not uv:
        raise CalibrationError(f"{source}: no calibration points (rows u, v, X, Y)")
    pts = np.array(xy, np.float64)
    return np.array(uv, np.float64), np.c_[pts, np.zeros(len(pts))]


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


# --------------------------------------------------------------------------- detection


@dataclass(frozen=True)
class RingDetection:
    """Calibration points found by :func:`detect_ring_points`.

    ``pixels``: (k, 2) sub-pixel (u_f, v_f) of each found point; ``indices``: (k,) its
    mark number (ascending); ``center_px``: where the marks' axes meet (px);
    ``dropped``: one line per mark candidate that was seen but not measured.
    """

    pixels: FloatArray
    indices: IntArray
    center_px: FloatArray
    dropped: tuple[str, ...] = ()


def _bilinear(img: NDArray[np.float32], pts: FloatArray) -> FloatArray:
    """Bilinear samples of ``img`` at (..., 2) (u, v) positions (edge-clamped)."""
    h, w = img.shape
    u = np.clip(pts[..., 0], 0.0, w - 1.000001)
    v = np.clip(pts[..., 1], 0.0, h - 1.000001)
    u0, v0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - u0, v - v0
    a = img[v0, u0] * (1 - fu) + img[v0, u0 + 1] * fu
    b = img[v0 + 1, u0] * (1 - fu) + img[v0 + 1, u0 + 1] * fu
    return np.asarray(a * (1 - fv) + b * fv, np.float64)


def _axes_meet(cents: FloatArray, dirs: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Least-squares meeting point of lines (c_i, e_i), dropping lines far from it."""
    keep = np.ones(len(cents), bool)
    centre = cents.mean(axis=0)
    for _ in range(5):
        n = np.stack([-dirs[:, 1], dirs[:, 0]], axis=1)
        if keep.sum() < 2:
            break
        A = n[keep]
        b = (n[keep] * cents[keep]).sum(axis=1)
        centre, *_ = np.linalg.lstsq(A, b, rcond=None)
        dist = np.abs((n * (cents - centre)).sum(axis=1))
        radius = np.linalg.norm(cents - centre, axis=1)
        new_keep = dist < np.maximum(0.06 * np.median(radius[keep]), 2.0)
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    return np.asarray(centre, np.float64), keep


def detect_ring_points(
    image: NDArray[np.uint8],
    *,
    n_marks: int = 16,
    mark_width_px: float | None = None,
    source: str = "the image",
) -> RingDetection:
    """The calibration points of the ring (inner end points of its marks) in an image.

    The ring is seen directly by the camera, around the mirror (Fig. 2.4): white paper,
    black radial marks touching the inner circle, the mirror inside it. Steps: the paper
    (Otsu threshold) is closed morphologically; what the closing adds are the marks.
    Their axes meet at the ring's centre; each mark's angle about it gives its number
    (mark k at ``2 pi k / n`` from the image's +u axis towards +v, as on the printed
    page, which assumes the camera's tilt about its axis is under half a mark spacing).
    Each mark is then measured to sub-pixel precision: its axis from grey-level moments
    of its outer part (paper on three sides), its inner end on that axis from the
    area of the intensity step between the mirror just inside and the black mark
    (exact for an area-sampled edge; assumes the mirror's image is roughly uniform over
    a few pixels there). Marks cut by the image border, or whose inner end has too
    little contrast against the mirror, are left out (listed in ``dropped``).

    Args:
        image: (H, W) or (H, W, 3) uint8.
        n_marks: marks on the ring (16 in sec. 2.3.2).
        mark_width_px: rough mark width in the image; default 3 % of the image's
            smaller side (only sets the closing kernel, which must be wider).
        source: name for error messages.

    Raises CalibrationError (one line, with the count) when fewer than
    :data:`MIN_POINTS` points are found.
    """
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    gray = np.ascontiguousarray(gray, np.uint8)
    h, w = gray.shape
    img = gray.astype(np.float32)
    _, paper = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    mw = 0.015 * min(h, w) if mark_width_px is None else float(mark_width_px)
    k = 2 * round(max(2.0, mw)) + 1
    closed = cv2.morphologyEx(
        paper, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    )
    cand = ((closed > 0) & (paper == 0)).astype(np.uint8)
    n_lab, labels, stats, _ = cv2.connectedComponentsWithStats(cand, connectivity=8)
    comps: list[tuple[FloatArray, FloatArray, FloatArray]] = []
    for lab in range(1, n_lab):
        x0, y0, bw, bh, area = stats[lab]
        if area < 12 or x0 <= 1 or y0 <= 1 or x0 + bw >= w - 1 or y0 + bh >= h - 1:
            continue
        ys, xs = np.nonzero(labels[y0 : y0 + bh, x0 : x0 + bw] == lab)
        pts = np.stack([xs + x0, ys + y0], axis=1).astype(np.float64)
        c = pts.mean(axis=0)
        evals, evecs = np.linalg.eigh(np.cov((pts - c).T))
        if evals[0] <= 0 or evals[1] / evals[0] < 2.0:
            continue
        comps.append((c, evecs[:, 1], pts))
    found = _label_and_measure(img, comps, n_marks)
    pixels, indices, centre, dropped = found
    if len(pixels) < MIN_POINTS:
        raise CalibrationError(
            f"{_PREFIX}: found {len(pixels)} of {n_marks} calibration points in {source}; "
            f"Tsai's coplanar calibration needs at least {MIN_POINTS}"
        )
    return RingDetection(pixels, indices, centre, tuple(dropped))


def _label_and_measure(
    img: NDArray[np.float32], comps: list[tuple[FloatArray, FloatArray, FloatArray]], n_marks: int
) -> tuple[FloatArray, IntArray, FloatArray, list[str]]:
    empty = (np.zeros((0, 2)), np.zeros(0, np.int64), np.full(2, np.nan))
    if len(comps) < 2:
        return (*empty, [])
    cents = np.array([c for c, _, _ in comps])
    dirs = np.array([d for _, d, _ in comps])
    centre, keep = _axes_meet(cents, dirs)
    step = 2 * np.pi / n_marks
    best: dict[int, tuple[float, int]] = {}
    for i in np.nonzero(keep)[0]:
        ang = math.atan2(cents[i, 1] - centre[1], cents[i, 0] - centre[0])
        kk = round(ang / step)
        dev = abs(ang - kk * step)
        kk %= n_marks
        if dev < step / 3 and (kk not in best or dev < best[kk][0]):
            best[kk] = (dev, int(i))
    pixels, indices, dropped = [], [], []
    for kk in sorted(best):
        c, e, pts = comps[best[kk][1]]
        if np.dot(e, c - centre) < 0:
            e = -e
        try:
            pixels.append(_measure_mark(img, c, e, pts))
            indices.append(kk)
        except _MarkError as err:
            dropped.append(f"mark {kk}: {err}")
    if not pixels:
        return (*empty[:2], centre, dropped)
    return np.array(pixels), np.array(indices, np.int64), centre, dropped


class _MarkError(Exception):
    pass


def _measure_mark(
    img: NDArray[np.float32], c: FloatArray, e: FloatArray, pts: FloatArray
) -> FloatArray:
    """Sub-pixel inner end point of one mark (see :func:`detect_ring_points`)."""
    s = (pts - c) @ e
    t = (pts - c) @ np.array([-e[1], e[0]])
    s_in, s_out = float(s.min()) - 0.5, float(s.max()) + 0.5
    half_w = max(float(np.abs(t).max()) + 0.5, 1.0)
    length = s_out - s_in
    if length < 6.0:
        raise _MarkError(f"too short ({length:.1f} px)")
    black = float(
        np.median(
            _bilinear(
                img, c + np.outer(np.linspace(s_in + 0.4 * length, s_out - 0.25 * length, 9), e)
            )
        )
    )
    n = np.array([-e[1], e[0]])
    side = _bilinear(
        img,
        c
        + np.outer(np.linspace(s_in + 0.5 * length, s_out, 9), e)[:, None, :]
        + np.array([-1.0, 1.0])[None, :, None] * (half_w + 2.5) * n,
    )
    paper = float(np.median(side))
    if paper - black < 20.0:
        raise _MarkError(f"too little contrast against the paper ({paper - black:.0f} grey levels)")
    # axis from grey-level moments of the outer part of the mark
    for _ in range(3):
        n = np.array([-e[1], e[0]])
        s_cut = s_in + 0.35 * length
        reach = half_w + 3.0
        corners = np.array(
            [c + sa * e + ta * n for sa in (s_cut - 1.0, s_out + 3.0) for ta in (-reach, reach)]
        )
        hh, ww = img.shape
        lo = np.maximum(np.floor(corners.min(axis=0)).astype(np.int64), 0)
        hi = np.minimum(np.ceil(corners.max(axis=0)).astype(np.int64), [ww - 1, hh - 1])
        gx, gy = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
        ij = np.stack([gx.ravel(), gy.ravel()], axis=1)
        p = ij.astype(np.float64)
        sp = (p - c) @ e
        tp = (p - c) @ n
        wgt = np.clip((paper - img[ij[:, 1], ij[:, 0]]) / (paper - black), 0.0, 1.0)
        wgt = wgt * np.clip(sp - s_cut + 0.5, 0.0, 1.0) * (np.abs(tp) <= half_w + 2.5)
        tot = wgt.sum()
        cen = (wgt[:, None] * p).sum(axis=0) / tot
        d = p - cen
        cov = (wgt[:, None, None] * d[:, :, None] * d[:, None, :]).sum(axis=0) / tot
        _, vecs = np.linalg.eigh(cov)
        e_new = vecs[:, 1] if np.dot(vecs[:, 1], e) > 0 else -vecs[:, 1]
        s_in -= float((cen - c) @ e)
        s_out -= float((cen - c) @ e)
        c, e = cen, e_new
    # inner end: area of the step mirror -> mark along the axis
    n = np.array([-e[1], e[0]])
    lateral = np.linspace(-0.5, 0.5, 7) * half_w
    end = s_in
    for _ in range(2):
        s_inside = np.linspace(end - 7.0, end - 3.0, 17)
        inside = float(np.median(_bilinear(img, c + np.outer(s_inside, e))))
        if abs(inside - black) < 0.15 * (paper - black):
            raise _MarkError(
                f"inner end not visible against the mirror ({inside - black:+.0f} grey levels)"
            )
        ds = 0.05
        sa, sb = end - 3.0, end + 3.0
        sg = np.arange(sa, sb + ds / 2, ds)
        prof = _bilinear(img, c + sg[:, None, None] * e + lateral[None, :, None] * n).mean(axis=1)
        frac = (prof - black) / (inside - black)
        end = sa + float(np.trapezoid(frac, sg))
    return np.asarray(c + end * e, np.float64)
