"""Fisheye and omni-camera calibration from chessboard / ChArUco views.

Three models: cv2.fisheye (KB4), cv2.omnidir (Mei) and OCamCalib's polynomial
(``scaramuzza``, :mod:`omnidev.fisheye.ocamcalib`).

Steps (docs/fisheye-calibration.md):

1. :func:`detect_corners`: a chessboard by :func:`omnidev.fisheye.board_detect.detect_chessboard`
   (``cv2.findChessboardCornersSB``, ``cv2.findChessboardCorners``, a grid grown from
   saddle points for strongly distorted omni-images, OpenCV's two on the image upsampled
   twice; every corner refined by
   ``cv2.cornerSubPix`` in a window fitted to its own squares), or
   ``cv2.aruco.CharucoDetector`` for a ChArUco board.
2. :func:`calibrate_views` runs the solver robustly: cv2.fisheye with
   ``CALIB_RECOMPUTE_EXTRINSIC | CALIB_CHECK_COND | CALIB_FIX_SKEW`` (when a view's pose
   is ill-conditioned, the view whose removal lets the solver converge is dropped and the
   solver rerun: OpenCV's message often names a victim, not the culprit),
   cv2.omnidir with ``CALIB_FIX_SKEW`` (views its initialisation rejects are the ones missing
   from its ``idx``), OCamCalib's linear initialisation with a centre search and a
   Levenberg-Marquardt refinement for ``scaramuzza`` (views the linear solution cannot image
   are dropped); then a view whose own reprojection RMS exceeds
   ``max(OUTLIER_MIN_PX, OUTLIER_FACTOR * median)`` is dropped (a misdetected board) and the
   solver rerun. Every drop is recorded with its reason.
3. Held-out error: K-fold cross-validation over the used views. Each fold is calibrated
   without its views; each held-out view's pose is then fitted with those intrinsics
   (:func:`fit_pose`: rays -> IPPE on the normalized plane, then Levenberg-Marquardt on the
   pixel reprojection error) and its reprojection RMS reported. The camera returned is the
   calibration on all used views.
4. Parameter uncertainty from the Jacobian of the reprojection residuals (numerical, intrinsics
   and every view's pose; the poses are eliminated by the Schur complement):
   standard deviations and correlations of the intrinsics, and warnings when the data leave a
   parameter poorly determined, when few views remain, or when the corners do not reach the
   image periphery.

RMS figures are the root mean square of the 2-D pixel error ``|uv_observed - uv_model|`` over
the corners (as OpenCV's calibration RMS). Pixels: (0, 0) is the centre of the top-left pixel.
Board frame and lengths (mm): :mod:`omnidev.fisheye.pattern`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.fisheye import ocamcalib as ocam
from omnidev.fisheye.board_detect import METHODS as BOARD_METHODS
from omnidev.fisheye.board_detect import detect_chessboard
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.models import KannalaBrandt, LensModel, Scaramuzza, Unified
from omnidev.fisheye.pattern import Pattern

FloatArray = NDArray[np.float64]
Image = NDArray[np.uint8]

MODELS = ("kb4", "mei", "scaramuzza")
PARAMS: dict[str, tuple[str, ...]] = {
    "kb4": ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"),
    "mei": ("fx", "fy", "cx", "cy", "xi", "k1", "k2", "p1", "p2"),
    "scaramuzza": ocam.PARAM_NAMES,
}
KB4_FLAGS = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_CHECK_COND | cv2.CALIB_FIX_SKEW
MEI_FLAGS = cv2.omnidir.CALIB_FIX_SKEW
# Mei distortion terms calibrate_views(fix=...) can hold at 0 (an option: the default, all free,
# is what a real lens needs; docs/fisheye-calibration.md, "Mei's fx and xi")
MEI_FIXABLE = {
    "k1": cv2.omnidir.CALIB_FIX_K1,
    "k2": cv2.omnidir.CALIB_FIX_K2,
    "p1": cv2.omnidir.CALIB_FIX_P1,
    "p2": cv2.omnidir.CALIB_FIX_P2,
}
CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 300, 1e-12)
OUTLIER_FACTOR = 4.0  # a view whose RMS exceeds this many times the median is dropped ...
OUTLIER_MIN_PX = 1.0  # ... if it also exceeds this
MIN_VIEWS = 3
FEW_VIEWS = 8  # fewer used views than this: a warning
MIN_CORNERS = 8  # a ChArUco view with fewer corners is not used
COVERAGE_WARN = 0.75  # corners reaching less of the way to the image border: a warning


# ---------------------------------------------------------------- detection


@dataclass(frozen=True)
class Detection:
    """The corners found in one image.

    Attributes:
        name: the image's name (file name), used in messages.
        image_points: (N, 2) pixels.
        object_points: (N, 3) the same corners in the board frame, mm.
        method: the detector that found them
            (:data:`omnidev.fisheye.board_detect.METHODS`, or ``charuco``).
    """

    name: str
    image_points: FloatArray
    object_points: FloatArray
    method: str = ""


def _grey(image: Image) -> Image:
    img = np.asarray(image)
    if img.ndim == 3:
        return np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), np.uint8)
    return np.asarray(img, np.uint8)


def detect_corners(
    image: Image,
    pattern: Pattern,
    *,
    name: str = "",
    methods: Sequence[str] | None = None,
) -> Detection | None:
    """The pattern's corners in a (H, W[, 3]) uint8 image, or None if the board is not found.

    A chessboard must be found whole, by
    :func:`omnidev.fisheye.board_detect.detect_chessboard` (``methods``: its detectors, in
    order; default all: ``cv2.findChessboardCornersSB``, ``cv2.findChessboardCorners``, a
    grid grown from saddle points, then OpenCV's two on the image upsampled twice), each
    corner refined by ``cv2.cornerSubPix`` in a window of 0.4 of its own spacing (2..7 px
    half-size).
    A ChArUco board may be partly visible; fewer than :data:`MIN_CORNERS` corners is None. Its
    corners are refined by ``cv2.cornerSubPix`` too, in a window that stays clear of the
    markers (a refinement that moves a corner by 1 px or more is not taken).
    """
    grey = _grey(image)
    if pattern.kind == "chessboard":
        found = detect_chessboard(grey, pattern.inner, methods=methods or BOARD_METHODS)
        if found is None:
            return None
        return Detection(name, found.uv, pattern.object_points(), found.method)
    detector = cv2.aruco.CharucoDetector(pattern.charuco_board())
    corners, ids, _, _ = detector.detectBoard(grey)
    if ids is None or len(ids) < MIN_CORNERS:
        return None
    uv = np.asarray(corners, np.float64).reshape(-1, 2)
    idx = np.asarray(ids, np.int64).ravel()
    # refine inside the marker-free cross around each corner: (square - marker) / 2 of a
    # square each way (a larger window takes in the markers' edges and pulls the corner)
    d = np.linalg.norm(uv[:, None] - uv[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    spacing = float(np.min(d))
    half = max(
        2, math.floor(spacing * (pattern.square_mm - pattern.marker_mm) / (2 * pattern.square_mm))
    )
    pts = uv.reshape(-1, 1, 2).astype(np.float32)
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
    refined = np.asarray(
        cv2.cornerSubPix(grey, pts, (half, half), (-1, -1), crit), np.float64
    ).reshape(-1, 2)
    keep = np.linalg.norm(refined - uv, axis=1) < 1.0
    uv[keep] = refined[keep]
    return Detection(name, uv, pattern.object_points()[idx], "charuco")


# ---------------------------------------------------------------- lens <-> parameters


def lens_from_params(model: str, p: Sequence[float] | FloatArray) -> LensModel:
    """A lens from the parameter vector named by :data:`PARAMS` (skew 0)."""
    v = [float(x) for x in p]
    if model == "scaramuzza":
        return ocam.lens_from_vector(v)
    if model == "kb4":
        return KannalaBrandt(v[0], v[1], v[2], v[3], (v[4], v[5], v[6], v[7]))
    return Unified(v[0], v[1], v[2], v[3], v[4], k1=v[5], k2=v[6], p1=v[7], p2=v[8])


def params_of(lens: LensModel) -> FloatArray:
    """The parameter vector of a KB4, Mei or Scaramuzza lens, in :data:`PARAMS` order."""
    if isinstance(lens, Scaramuzza):
        return ocam.vector_of(lens)
    if isinstance(lens, KannalaBrandt):
        return np.array([lens.fx, lens.fy, lens.cx, lens.cy, *lens.k], np.float64)
    if isinstance(lens, Unified):
        return np.array(
            [lens.fx, lens.fy, lens.cx, lens.cy, lens.xi, lens.k1, lens.k2, lens.p1, lens.p2],
            np.float64,
        )
    raise ValueError(f"no calibration parameters for lens model {lens.name!r}")


def effective_focal(lens: LensModel) -> tuple[float, float]:
    """(fx, fy) of the image scale at the optical axis, px per rad.

    KB4: fx, fy. Mei: fx / (1 + xi), fy / (1 + xi) (``r = f sin t / (cos t + xi)``).
    Scaramuzza: -ss[0] along columns, -c ss[0] along rows (the angle from the axis is
    ``atan2(rho, -ss(rho))``, rho / -ss[0] near the axis).
    """
    if isinstance(lens, Scaramuzza):
        return -lens.ss[0], -lens.c * lens.ss[0]
    if isinstance(lens, Unified):
        return lens.fx / (1 + lens.xi), lens.fy / (1 + lens.xi)
    if isinstance(lens, KannalaBrandt):
        return lens.fx, lens.fy
    raise ValueError(f"no focal length for lens model {lens.name!r}")


# ---------------------------------------------------------------- poses, residuals


def principal_point(lens: LensModel) -> tuple[float, float]:
    """(u, v) px of the optical axis's image (KB4, Mei: (cx, cy); Scaramuzza: (yc, xc))."""
    if isinstance(lens, Scaramuzza):
        return lens.yc, lens.xc
    p = params_of(lens)
    return float(p[2]), float(p[3])


def _rot(rvec: FloatArray) -> FloatArray:
    r, _ = cv2.Rodrigues(np.asarray(rvec, np.float64).reshape(3, 1))
    return np.asarray(r, np.float64)


def reproject(lens: LensModel, obj: FloatArray, rvec: FloatArray, tvec: FloatArray) -> FloatArray:
    """(N, 2) pixels of board points ``obj`` (mm) at pose (rvec, tvec): board -> optical."""
    cam = obj @ _rot(rvec).T + np.asarray(tvec, np.float64).ravel()
    uv, _ = lens.project(cam)
    return np.asarray(uv, np.float64)


def rms_px(err: FloatArray) -> float:
    """Root mean square of the 2-D errors (N, 2), px."""
    e = np.asarray(err, np.float64).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1)))) if len(e) else math.nan


def _pose_jacobian(
    lens: LensModel, obj: FloatArray, pose: FloatArray, base: FloatArray
) -> FloatArray:
    jac = np.empty((base.size, 6))
    for k in range(6):
        h = 1e-7 if k < 3 else 1e-6 * max(1.0, float(np.linalg.norm(pose[3:])))
        q = pose.copy()
        q[k] += h
        jac[:, k] = (reproject(lens, obj, q[:3], q[3:]).ravel() - base) / h
    return jac


def _look_at(d: FloatArray) -> FloatArray:
    """A rotation taking unit vector ``d`` to +z."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(d, z)
    s = float(np.linalg.norm(axis))
    c = float(np.dot(d, z))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    r, _ = cv2.Rodrigues(axis / s * math.atan2(s, c))
    return np.asarray(r, np.float64)


def fit_pose(
    lens: LensModel, obj: FloatArray, uv: FloatArray, *, iterations: int = 30
) -> tuple[FloatArray, FloatArray] | None:
    """The board pose (rvec, tvec; board -> optical frame, mm) that best reprojects ``uv``.

    Initial pose: the corners are unprojected to rays, the rays are turned so that their
    mean direction is the z axis (a board beyond 90 degrees from the optical axis, as an
    omni-camera sees it, then lies in front of a virtual pinhole), rays within 80 degrees of
    that direction go on its normalized plane, and ``cv2.solvePnP`` (IPPE, planar board)
    solves it; then Levenberg-Marquardt on the pixel reprojection error. None if fewer than
    4 corners are usable.
    """
    rays, ok = lens.unproject(uv)
    if int(ok.sum()) < 4:
        return None
    mean = np.sum(rays[ok], axis=0)
    if not float(np.linalg.norm(mean)) > 0:
        return None
    turn = _look_at(mean / np.linalg.norm(mean))  # turn @ mean = +z
    local = rays @ turn.T
    use = ok & (np.nan_to_num(local[:, 2]) > math.cos(math.radians(80.0)))
    if int(use.sum()) < 4:
        return None
    norm = local[use, :2] / local[use, 2:]
    found, rvec, tvec = cv2.solvePnP(obj[use], norm, np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
    if not found:
        return None
    rot = turn.T @ _rot(np.ravel(rvec))
    rv, _ = cv2.Rodrigues(rot)
    pose = np.concatenate([np.ravel(rv), turn.T @ np.ravel(tvec)]).astype(np.float64)
    target = np.asarray(uv, np.float64).ravel()
    lam = 1e-3
    res = reproject(lens, obj, pose[:3], pose[3:]).ravel() - target
    cost = float(np.nansum(res * res))
    for _ in range(iterations):
        if not np.all(np.isfinite(res)):
            return None
        jac = _pose_jacobian(lens, obj, pose, res + target)
        a = jac.T @ jac
        g = jac.T @ res
        improved = False
        for _ in range(10):
            step = np.linalg.solve(a + lam * np.diag(np.diag(a) + 1e-12), -g)
            trial = pose + step
            r2 = reproject(lens, obj, trial[:3], trial[3:]).ravel() - target
            c2 = float(np.sum(r2 * r2)) if np.all(np.isfinite(r2)) else math.inf
            if c2 < cost:
                pose, res, cost, lam = trial, r2, c2, max(lam / 10, 1e-9)
                improved = True
                break
            lam *= 10
        if not improved or float(np.abs(step).max()) < 1e-12:
            break
    return pose[:3].copy(), pose[3:].copy()


# ---------------------------------------------------------------- the solvers


@dataclass
class _Solve:
    lens: LensModel
    used: list[int]  # indices into the views given
    rvecs: list[FloatArray]
    tvecs: list[FloatArray]
    dropped: dict[int, str] = field(default_factory=dict)


_COND = re.compile(r"input array (\d+)")


def _fisheye_calibrate(
    obj: list[FloatArray], img: list[FloatArray], idx: list[int], size: tuple[int, int]
) -> tuple[float, FloatArray, FloatArray, list[FloatArray], list[FloatArray]]:
    rms, k, d, rvecs, tvecs = cv2.fisheye.calibrate(
        [obj[i].reshape(1, -1, 3) for i in idx],
        [img[i].reshape(1, -1, 2) for i in idx],
        size,
        np.zeros((3, 3)),
        np.zeros(4),
        flags=KB4_FLAGS,
        criteria=CRITERIA,
    )
    return (
        float(rms),
        np.asarray(k, np.float64),
        np.asarray(d, np.float64).ravel(),
        [np.ravel(r) for r in rvecs],
        [np.ravel(t) for t in tvecs],
    )


def _ill_conditioned(
    obj: list[FloatArray], img: list[FloatArray], idx: list[int], size: tuple[int, int], named: int
) -> tuple[int, str]:
    """The position in ``idx`` of the view that makes CALIB_CHECK_COND fail, and why.

    OpenCV's message names the view whose pose turned ill-conditioned, which is often not the
    culprit: one bad view (a tiny, far board) spoils the intrinsics and then another view's
    pose fails. So each view is left out in turn; the one whose removal lets the solver
    converge with the lowest RMS is it. If no single removal helps, the named view goes.
    """
    best: tuple[float, int] | None = None
    if len(idx) - 1 >= MIN_VIEWS:
        for j in range(len(idx)):
            try:
                rms = _fisheye_calibrate(obj, img, idx[:j] + idx[j + 1 :], size)[0]
            except cv2.error:
                continue
            if best is None or rms < best[0]:
                best = (rms, j)
    if best is not None:
        return best[1], (
            "ill-conditioned (cv2.fisheye CALIB_CHECK_COND fails with it and converges without it)"
        )
    return named, "ill-conditioned pose (named by cv2.fisheye CALIB_CHECK_COND)"


def _run_kb4(
    obj: list[FloatArray], img: list[FloatArray], size: tuple[int, int]
) -> tuple[LensModel, list[FloatArray], list[FloatArray], list[int], dict[int, str]]:
    idx = list(range(len(obj)))
    dropped: dict[int, str] = {}
    while True:
        if len(idx) < MIN_VIEWS:
            return _few(idx, dropped)
        try:
            _, km, dd, rvecs, tvecs = _fisheye_calibrate(obj, img, idx, size)
        except cv2.error as exc:
            m = _COND.search(str(exc))
            if m is None or int(m.group(1)) >= len(idx):
                raise CalibrationError(
                    f"cv2.fisheye.calibrate failed: {_first_line(exc)}"
                ) from None
            j, why = _ill_conditioned(obj, img, idx, size, int(m.group(1)))
            dropped[idx.pop(j)] = why
            continue
        lens = KannalaBrandt(
            float(km[0, 0]),
            float(km[1, 1]),
            float(km[0, 2]),
            float(km[1, 2]),
            (float(dd[0]), float(dd[1]), float(dd[2]), float(dd[3])),
        )
        return lens, rvecs, tvecs, idx, dropped


def _run_mei(
    obj: list[FloatArray], img: list[FloatArray], size: tuple[int, int], flags: int = MEI_FLAGS
) -> tuple[LensModel, list[FloatArray], list[FloatArray], list[int], dict[int, str]]:
    if len(obj) < MIN_VIEWS:
        return _few(list(range(len(obj))), {})
    try:
        _, k, xi, d, rvecs, tvecs, used = cv2.omnidir.calibrate(
            [obj[i].reshape(1, -1, 3) for i in range(len(obj))],
            [img[i].reshape(1, -1, 2) for i in range(len(obj))],
            size,
            np.zeros((3, 3)),
            np.zeros(1),
            np.zeros(4),
            flags,
            CRITERIA,
        )
    except cv2.error as exc:
        raise CalibrationError(f"cv2.omnidir.calibrate failed: {_first_line(exc)}") from None
    idx = [int(i) for i in np.asarray(used).ravel()] if used is not None else []
    dropped = {
        i: "rejected by cv2.omnidir's initialisation" for i in range(len(obj)) if i not in idx
    }
    if len(idx) < MIN_VIEWS:
        return _few(idx, dropped)
    km = np.asarray(k, np.float64)
    dd = np.asarray(d, np.float64).ravel()
    lens = Unified(
        float(km[0, 0]),
        float(km[1, 1]),
        float(km[0, 2]),
        float(km[1, 2]),
        float(np.asarray(xi).ravel()[0]),
        k1=float(dd[0]),
        k2=float(dd[1]),
        p1=float(dd[2]),
        p2=float(dd[3]),
    )
    return lens, [np.ravel(r) for r in rvecs], [np.ravel(t) for t in tvecs], idx, dropped


def _run_scaramuzza(
    obj: list[FloatArray], img: list[FloatArray], size: tuple[int, int]
) -> tuple[LensModel, list[FloatArray], list[FloatArray], list[int], dict[int, str]]:
    """OCamCalib's linear solution with the centre search, then the refinement.

    A view that the linear solution does not image (a corner with no real root of the
    polynomial) is dropped and the search rerun without it.
    """
    idx = list(range(len(obj)))
    dropped: dict[int, str] = {}
    while True:
        if len(idx) < MIN_VIEWS:
            return _few(idx, dropped)
        o = [obj[i] for i in idx]
        q = [img[i] for i in idx]
        try:
            lin = ocam.find_centre(o, q, size)
        except ocam.OcamCalibError as exc:
            raise CalibrationError(f"OCamCalib initialisation failed: {exc}") from None
        bad = [
            j
            for j in range(len(idx))
            if not np.all(
                np.isfinite(ocam.reprojection(lin.lens, o[j], lin.rvecs[j], lin.tvecs[j]))
            )
        ]
        if bad:
            for j in bad:
                dropped[idx[j]] = "not imaged by the linear (OCamCalib) initialisation"
            idx = [i for j, i in enumerate(idx) if j not in bad]
            continue
        try:
            ref = ocam.refine(lin.lens, o, q, lin.rvecs, lin.tvecs)
        except ocam.OcamCalibError as exc:
            raise CalibrationError(f"OCamCalib refinement failed: {exc}") from None
        return ref.lens, ref.rvecs, ref.tvecs, idx, dropped


class _TooFewError(Exception):
    def __init__(self, used: list[int], dropped: dict[int, str]) -> None:
        super().__init__("too few views")
        self.used = used
        self.dropped = dropped


def _few(
    idx: list[int], dropped: dict[int, str]
) -> tuple[LensModel, list[FloatArray], list[FloatArray], list[int], dict[int, str]]:
    raise _TooFewError(idx, dropped)


def _first_line(exc: BaseException) -> str:
    lines = [s.strip() for s in str(exc).splitlines() if s.strip()]
    return lines[-1] if lines else type(exc).__name__


def _solve(
    model: str,
    obj: list[FloatArray],
    img: list[FloatArray],
    size: tuple[int, int],
    fix: Sequence[str] = (),
) -> _Solve:
    """The solver on views ``obj``/``img``, dropping rejected and outlying views.

    ``fix``: Mei distortion terms held at 0. Raises _TooFewError when fewer than MIN_VIEWS
    views remain.
    """
    mei_flags = MEI_FLAGS
    for name in fix:
        mei_flags |= MEI_FIXABLE[name]

    def run(
        o: list[FloatArray], i: list[FloatArray], sz: tuple[int, int]
    ) -> tuple[LensModel, list[FloatArray], list[FloatArray], list[int], dict[int, str]]:
        if model == "scaramuzza":
            return _run_scaramuzza(o, i, sz)
        return _run_kb4(o, i, sz) if model == "kb4" else _run_mei(o, i, sz, mei_flags)

    keep = list(range(len(obj)))
    dropped: dict[int, str] = {}
    while True:
        try:
            lens, rvecs, tvecs, used, drops = run(
                [obj[i] for i in keep], [img[i] for i in keep], size
            )
        except _TooFewError as few:
            dropped.update({keep[i]: why for i, why in few.dropped.items()})
            raise _TooFewError([keep[i] for i in few.used], dropped) from None
        dropped.update({keep[i]: why for i, why in drops.items()})
        used = [keep[i] for i in used]
        errs = [
            rms_px(reproject(lens, obj[i], r, t) - img[i])
            for i, r, t in zip(used, rvecs, tvecs, strict=True)
        ]
        med = float(np.median(errs))
        worst = int(np.argmax(errs))
        limit = max(OUTLIER_MIN_PX, OUTLIER_FACTOR * med)
        if (errs[worst] > limit or not math.isfinite(errs[worst])) and len(used) > MIN_VIEWS:
            dropped[used[worst]] = (
                f"outlier: reprojection RMS {errs[worst]:.2f} px > {limit:.2f} px "
                f"({OUTLIER_FACTOR:g} x the median)"
            )
            keep = [i for i in used if i != used[worst]]
            continue
        return _Solve(lens, used, rvecs, tvecs, dropped)


# ---------------------------------------------------------------- uncertainty


def intrinsic_covariance(
    model: str,
    lens: LensModel,
    obj: Sequence[FloatArray],
    img: Sequence[FloatArray],
    rvecs: Sequence[FloatArray],
    tvecs: Sequence[FloatArray],
    *,
    fixed: Sequence[str] = (),
    sigma_px: float | None = None,
) -> FloatArray:
    """Covariance of the intrinsics (:data:`PARAMS` order) with the view poses eliminated.

    Gauss-Newton approximation ``sigma^2 (J^T J)^-1`` from numerical Jacobians,
    ``sigma^2`` = residual sum of squares / (residuals - parameters), or ``sigma_px**2``
    when the corner noise (px on each of u and v) is known: with the true lens, poses and
    corners that is the Cramer-Rao bound of an unbiased calibration. Parameters named in
    ``fixed`` are held (their rows and columns are 0).
    """
    names = PARAMS[model]
    unknown = [f for f in fixed if f not in names]
    if unknown:
        raise ValueError(f"fixed: {', '.join(unknown)} not among {', '.join(names)}")
    p0 = params_of(lens)
    free = [k for k, n in enumerate(names) if n not in fixed]
    n_par = len(free)
    a = np.zeros((n_par, n_par))
    ssr = 0.0
    n_res = 0
    for o, uv, r, t in zip(obj, img, rvecs, tvecs, strict=True):
        base = reproject(lens, o, r, t).ravel()
        res = base - np.asarray(uv, np.float64).ravel()
        ssr += float(res @ res)
        n_res += res.size
        ji = np.empty((res.size, n_par))
        for col, k in enumerate(free):
            h = 1e-6 * max(1.0, abs(float(p0[k])))
            q = p0.copy()
            q[k] += h
            ji[:, col] = (reproject(lens_from_params(model, q), o, r, t).ravel() - base) / h
        jp = _pose_jacobian(lens, o, np.concatenate([np.ravel(r), np.ravel(t)]), base)
        c = jp.T @ jp
        b = ji.T @ jp
        a += ji.T @ ji - b @ np.linalg.solve(c, b.T)
    if sigma_px is None:
        dof = max(n_res - n_par - 6 * len(obj), 1)
        sigma2 = ssr / dof
    else:
        sigma2 = float(sigma_px) ** 2
    cov = np.zeros((len(p0), len(p0)))
    cov[np.ix_(free, free)] = np.linalg.pinv(a) * sigma2
    return cov


# ---------------------------------------------------------------- results


Status = Literal["used", "dropped", "not found"]


@dataclass(frozen=True)
class ViewError:
    """One image's part in the calibration.

    Attributes:
        name: the image's name.
        status: ``used`` (a training view of the returned camera), ``dropped`` (the solver
            rejected it; ``note`` says why) or ``not found`` (no board detected).
        n_points: corners detected.
        train_rms_px: reprojection RMS with the final calibration and the view's own
            calibrated pose (used views; NaN otherwise).
        heldout_rms_px: reprojection RMS when the view was held out: intrinsics calibrated
            without it, its pose fitted to it (used views, with K-fold; for dropped views:
            the final intrinsics and a fitted pose). NaN when not measured.
        note: why a view was dropped, or other remarks.
    """

    name: str
    status: Status
    n_points: int
    train_rms_px: float
    heldout_rms_px: float
    note: str = ""


@dataclass(frozen=True)
class FisheyeCalibration:
    """The result of :func:`calibrate_views`.

    Attributes:
        camera: the calibrated camera (lens in the optical frame, the given mount).
        model: ``kb4``, ``mei`` or ``scaramuzza``.
        flags: the solver flags used, as text.
        train_rms_px: RMS over all used views' corners with the final calibration.
        heldout_rms_px: RMS over all used views' corners, each with the fold that held it out
            (NaN if no held-out evaluation).
        folds: number of folds (0: none).
        views: every image, in the order given.
        std: standard deviation of every intrinsic (:data:`PARAMS` names).
        correlation: (P, P) correlation matrix of the intrinsics.
        coverage: largest corner distance from the principal point / the distance from the
            principal point to the nearest image border.
        warnings: one line each: parameters poorly determined, too few views, poor coverage.
    """

    camera: FisheyeCamera
    model: str
    flags: str
    train_rms_px: float
    heldout_rms_px: float
    folds: int
    views: tuple[ViewError, ...]
    std: dict[str, float]
    correlation: FloatArray
    coverage: float
    warnings: tuple[str, ...]

    @property
    def params(self) -> dict[str, float]:
        return dict(zip(PARAMS[self.model], params_of(self.camera.lens).tolist(), strict=True))


def _flag_names(model: str, fix: Sequence[str] = ()) -> str:
    if model == "kb4":
        return (
            "cv2.fisheye.calibrate: CALIB_RECOMPUTE_EXTRINSIC | CALIB_CHECK_COND | CALIB_FIX_SKEW"
        )
    if model == "scaramuzza":
        return (
            "OCamCalib: linear initialisation with centre search, Levenberg-Marquardt on all "
            "intrinsics (degree 4, ss[1] = 0, symmetric affine) and poses"
        )
    return "cv2.omnidir.calibrate: " + " | ".join(
        ["CALIB_FIX_SKEW"] + [f"CALIB_FIX_{n.upper()}" for n in MEI_FIXABLE if n in fix]
    )


_OCTANTS = (
    "right",
    "lower right",
    "bottom",
    "lower left",
    "left",
    "upper left",
    "top",
    "upper right",
)


def _coverage(
    lens: LensModel, size: tuple[int, int], img: Sequence[FloatArray]
) -> tuple[float, list[str], float]:
    """Reach of the corners toward the border (fraction) and the outer octants with none."""
    w, h = size
    cx, cy = principal_point(lens)
    inner = min(cx + 0.5, w - 0.5 - cx, cy + 0.5, h - 0.5 - cy)
    pts = np.concatenate([np.asarray(p).reshape(-1, 2) for p in img])
    d = pts - [cx, cy]
    r = np.hypot(d[:, 0], d[:, 1])
    reach = float(r.max() / inner) if inner > 0 else 0.0
    az = np.arctan2(d[:, 1], d[:, 0])  # image angle, v down: 90 deg = bottom
    octant = np.floor((az + math.pi / 8) / (math.pi / 4)).astype(int) % 8
    outer = r > 0.6 * inner
    missing = [_OCTANTS[k] for k in range(8) if not np.any(outer & (octant == k))]
    return reach, missing, float(r.max())


def projection_sigma_px(
    model: str,
    lens: LensModel,
    size: tuple[int, int],
    cov: FloatArray,
    *,
    within_px: float = math.inf,
    n: int = 25,
) -> tuple[FloatArray, FloatArray]:
    """1-sigma uncertainty (px) of the projection over an n x n grid of image pixels.

    The grid pixels within ``within_px`` of the principal point are unprojected with ``lens``;
    a change of the intrinsics moves their images by ``J dp`` (J: numerical derivative by the
    intrinsics). The part of that motion a rotation of the camera explains (a shift of the
    principal point against the board poses, say) is removed by least squares, since it is
    not an error of the lens model; the rest gets the covariance ``P J cov J^T P^T`` and the
    figure is ``sqrt(trace)`` per pixel. Returns (M, 2) pixels and (M,) sigmas.
    """
    w, h = size
    p0 = params_of(lens)
    uu, vv = np.meshgrid(np.linspace(0, w - 1, n), np.linspace(0, h - 1, n))
    uv = np.stack([uu.ravel(), vv.ravel()], -1)
    pu, pv = principal_point(lens)
    near = np.hypot(uv[:, 0] - pu, uv[:, 1] - pv) <= within_px
    rays, ok = lens.unproject(uv[near])
    rays, uv = rays[ok], uv[near][ok]
    if len(uv) == 0:
        return uv, np.zeros(0)
    jac = np.zeros((len(uv), 2, len(p0)))
    for k in range(len(p0)):
        step = 1e-6 * max(1.0, abs(float(p0[k])))
        q = p0.copy()
        q[k] += step
        moved, _ = lens_from_params(model, q).project(rays)
        jac[:, :, k] = (moved - uv) / step
    jrot = np.zeros((len(uv), 2, 3))
    for k in range(3):
        omega = np.zeros(3)
        omega[k] = 1e-6
        moved, _ = lens.project(rays + np.cross(omega, rays))
        jrot[:, :, k] = (moved - uv) / 1e-6
    jr = jrot.reshape(-1, 3)
    proj = np.eye(len(jr)) - jr @ np.linalg.pinv(jr)
    jp = proj @ jac.reshape(-1, len(p0))
    var = np.einsum("ik,kl,il->i", jp, cov, jp).reshape(-1, 2).sum(axis=1)
    return uv, np.sqrt(np.clip(var, 0, None))


FOCAL_REL_WARN = 0.0025  # relative 1-sigma of the focal length
CENTRE_WARN_PX = 1.0  # 1-sigma of the principal point
XI_WARN = 0.02  # 1-sigma of xi
PROJECTION_WARN_PX = 0.5  # 1-sigma of the projection where the corners reach


def _warnings(
    model: str,
    lens: LensModel,
    size: tuple[int, int],
    n_used: int,
    cov: FloatArray,
    reach: float,
    missing: list[str],
    reach_px: float,
) -> list[str]:
    out: list[str] = []
    names = PARAMS[model]
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.nan_to_num(cov / np.outer(std, std))
    p = params_of(lens)
    if n_used < FEW_VIEWS:
        out.append(
            f"only {n_used} views used: the parameters rest on little data; take "
            f"{FEW_VIEWS} or more, tilted, with boards reaching the image border"
        )
    if reach < COVERAGE_WARN:
        out.append(
            f"the corners reach only {100 * reach:.0f} % of the way from the principal point "
            "to the image border: the distortion beyond is extrapolated; add views with the "
            "board near the border"
        )
    elif missing:
        out.append(
            "no corners in the outer part of the image toward the "
            + ", ".join(missing)
            + ": add views with the board there"
        )

    siblings = ({"fx", "fy"}, {"cx", "cy"})  # fx's partner is fy by construction: say the next

    def partner(k: int) -> str:
        others = [j for j in range(len(names)) if j != k and {names[k], names[j]} not in siblings]
        j = max(others, key=lambda j: abs(corr[k, j]))
        return f"correlation with {names[j]} {corr[k, j]:+.3f}"

    for k, name in enumerate(names):
        bad = (
            (name in ("fx", "fy", "a0") and std[k] > FOCAL_REL_WARN * abs(p[k]))
            or (name in ("cx", "cy") and std[k] > CENTRE_WARN_PX)
            or (name == "xi" and std[k] > XI_WARN)
        )
        if bad:
            rel = (
                f"{100 * std[k] / abs(p[k]):.3g} %; " if name in ("fx", "fy", "a0") and p[k] else ""
            )
            out.append(
                f"{name} is poorly determined: {p[k]:.6g} +- {std[k]:.3g} (1 sigma; {rel}"
                f"{partner(k)})"
            )
    if model == "mei" and any(w.startswith(("fx ", "fy ", "xi ")) for w in out):
        g = np.zeros(len(names))
        g[0] = 1 / (1 + p[4])
        g[4] = -p[0] / (1 + p[4]) ** 2
        f_eff = p[0] / (1 + p[4])
        s_eff = math.sqrt(max(float(g @ cov @ g), 0.0))
        out.append(
            f"Mei's fx and xi are not separately determined by these views: fx {p[0]:.6g} "
            f"+- {std[0]:.3g} px ({100 * std[0] / abs(p[0]):.3g} %), xi {p[4]:.4g} +- "
            f"{std[4]:.3g} (1 sigma; correlation {corr[0, 4]:+.3f}). They trade off against "
            f"k1 and k2 (exactly at xi = 1, docs/fisheye-calibration.md); the image scale at "
            f"the axis fx / (1 + xi) = {f_eff:.6g} +- {s_eff:.2g} px/rad is determined. Use "
            "the camera for its projection, not its fx or xi alone"
        )
    uv, sig = projection_sigma_px(model, lens, size, cov, within_px=reach_px)
    if len(sig):
        worst = int(np.argmax(sig))
        if sig[worst] > PROJECTION_WARN_PX:
            out.append(
                f"the projection is uncertain by up to {sig[worst]:.2f} px (1 sigma) where the "
                f"corners reach, at pixel ({uv[worst, 0]:.0f}, {uv[worst, 1]:.0f}): add views"
            )
    return out


def _rms_views(
    lens: LensModel,
    obj: Sequence[FloatArray],
    img: Sequence[FloatArray],
    rvecs: Sequence[FloatArray],
    tvecs: Sequence[FloatArray],
) -> list[FloatArray]:
    return [
        reproject(lens, o, r, t) - uv for o, uv, r, t in zip(obj, img, rvecs, tvecs, strict=True)
    ]


def _heldout_error(lens: LensModel, obj: FloatArray, uv: FloatArray) -> FloatArray | None:
    pose = fit_pose(lens, obj, uv)
    if pose is None:
        return None
    return reproject(lens, obj, pose[0], pose[1]) - uv


def calibrate_views(
    detections: Sequence[Detection | None],
    image_size: tuple[int, int],
    model: str,
    *,
    names: Sequence[str] | None = None,
    holdout: int = 4,
    mount: FloatArray | None = None,
    progress: Callable[[str], None] | None = None,
    fix: Sequence[str] = (),
) -> FisheyeCalibration:
    """Calibrate a KB4, Mei or Scaramuzza (OCamCalib) lens from the detected corners.

    Args:
        detections: one per image, None where no board was found.
        image_size: (width, height) of every image, px.
        model: ``"kb4"`` (cv2.fisheye), ``"mei"`` (cv2.omnidir) or ``"scaramuzza"``
            (:mod:`omnidev.fisheye.ocamcalib`).
        names: the images' names for the report (default: the detections' names).
        holdout: K of the K-fold held-out evaluation (0: none; at most the number of views).
        mount: the camera's mount (:data:`omnidev.fisheye.camera.MOUNTS`), default up.
        progress: called with a short message before each solver run.
        fix: Mei only, an option for a lens known to have none of them: distortion terms
            (``k1``, ``k2``, ``p1``, ``p2``) held at 0. Default: all free, as a real lens
            needs. Holding k1 and k2 makes fx and xi identifiable, but a lens that has them
            then gets a biased fx that the held-out RMS does not reveal (a warning says so;
            docs/fisheye-calibration.md).

    Raises:
        CalibrationError: no board in any image, fewer than 3 usable views, a solver failure.
    """
    if model not in MODELS:
        raise CalibrationError(f"model {model!r}: choose from {', '.join(MODELS)}")
    fix = tuple(fix)
    if fix and model != "mei":
        raise CalibrationError(f"fix {', '.join(fix)}: holding parameters is for --model mei")
    bad = [n for n in fix if n not in MEI_FIXABLE]
    if bad:
        raise CalibrationError(
            f"fix {', '.join(bad)}: the Mei terms that can be held are {', '.join(MEI_FIXABLE)}"
        )
    names = (
        list(names)
        if names is not None
        else [d.name if d is not None else f"image {i}" for i, d in enumerate(detections)]
    )
    found = [i for i, d in enumerate(detections) if d is not None]
    if not found:
        raise CalibrationError(
            f"no board found in any of the {len(detections)} images"
            + (f" ({names[0]} ...)" if names else "")
        )
    if len(found) < MIN_VIEWS:
        raise CalibrationError(
            f"a board was found in only {len(found)} image(s) ("
            + ", ".join(names[i] for i in found)
            + f"); at least {MIN_VIEWS} views are needed"
        )
    obj = [detections[i].object_points for i in found]  # type: ignore[union-attr]
    img = [detections[i].image_points for i in found]  # type: ignore[union-attr]
    say = progress or (lambda _msg: None)
    say(f"calibrating {model} on {len(found)} views")
    try:
        final = _solve(model, obj, img, image_size, fix)
    except _TooFewError as few:
        usable = ", ".join(names[found[i]] for i in few.used) or "none"
        raise CalibrationError(
            f"only {len(few.used)} usable view(s) after dropping the rejected ones ({usable}); "
            f"at least {MIN_VIEWS} are needed"
        ) from None
    lens = final.lens
    train = _rms_views(
        lens, [obj[i] for i in final.used], [img[i] for i in final.used], final.rvecs, final.tvecs
    )
    train_by = dict(zip(final.used, train, strict=True))

    # K-fold held-out errors over the used views
    k = min(int(holdout), len(final.used))
    held: dict[int, FloatArray] = {}
    notes: dict[int, str] = {}
    if k >= 2:
        for f in range(k):
            out_idx = final.used[f::k]
            in_idx = [i for i in final.used if i not in out_idx]
            say(f"held-out fold {f + 1}/{k}")
            try:
                fold = _solve(
                    model, [obj[i] for i in in_idx], [img[i] for i in in_idx], image_size, fix
                )
            except (_TooFewError, CalibrationError):
                for i in out_idx:
                    notes[i] = f"fold {f + 1} could not be calibrated"
                continue
            for i in out_idx:
                e = _heldout_error(fold.lens, obj[i], img[i])
                if e is None:
                    notes[i] = "held-out pose not found"
                else:
                    held[i] = e
    elif k == 1:
        k = 0
    for i, why in final.dropped.items():
        e = _heldout_error(lens, obj[i], img[i])
        if e is not None:
            held[i] = e
        notes[i] = why

    # uncertainty, warnings
    cov = intrinsic_covariance(
        model,
        lens,
        [obj[i] for i in final.used],
        [img[i] for i in final.used],
        final.rvecs,
        final.tvecs,
        fixed=fix,
    )
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(std, std)
    corr = np.nan_to_num(corr)
    reach, missing, reach_px = _coverage(lens, image_size, [img[i] for i in final.used])
    warns = _warnings(model, lens, image_size, len(final.used), cov, reach, missing, reach_px)
    if fix:
        warns.append(
            f"{', '.join(fix)} held at 0 (fix): fx, xi and the uncertainties assume the lens "
            "has no such distortion; if it has, fx and xi come out biased by many sigmas "
            "while the held-out RMS stays as low (docs/fisheye-calibration.md)"
        )

    views: list[ViewError] = []
    pos = {j: n for n, j in enumerate(found)}
    for i, name in enumerate(names):
        if i not in pos:
            views.append(ViewError(name, "not found", 0, math.nan, math.nan, "no board found"))
            continue
        j = pos[i]
        n = len(img[j])
        h_rms = rms_px(held[j]) if j in held else math.nan
        if j in train_by:
            views.append(ViewError(name, "used", n, rms_px(train_by[j]), h_rms, notes.get(j, "")))
        else:
            views.append(ViewError(name, "dropped", n, math.nan, h_rms, notes.get(j, "")))
    held_used = [held[j] for j in final.used if j in held]
    heldout = rms_px(np.concatenate(held_used)) if held_used and k else math.nan
    if isinstance(lens, Scaramuzza):
        # the file gets OCamCalib's world2cam polynomial (fast maps); the figures above are
        # of the exact model (ss root), which it follows to 0.01 px over the image
        lens = ocam.fit_invpol(lens, image_size)
    camera = FisheyeCamera(lens, image_size, MOUNTS["up"] if mount is None else mount)
    return FisheyeCalibration(
        camera=camera,
        model=model,
        flags=_flag_names(model, fix),
        train_rms_px=rms_px(np.concatenate(train)),
        heldout_rms_px=heldout,
        folds=k,
        views=tuple(views),
        std=dict(zip(PARAMS[model], std.tolist(), strict=True)),
        correlation=corr,
        coverage=reach,
        warnings=tuple(warns),
    )
