"""Render omni-images through a misaligned (non-SVP) hyperbolic-mirror camera, with exact truth.

This is the independent truth that ``omnidev.nonsvp`` is tested against: it uses
the model's *parameter* dataclasses (Mirror, Lens, Pose, NonSvpCamera) but none
of its projection code. Each output pixel is supersampled; every sample is a
plain vector ray trace: a ray from the lens centre through the pixel's ideal
image point, its first hit with the mirror's hyperboloid sheet (within the rim),
the reflection r = d - 2 (d . n) n, and the scene along r.

Frames, as read from dissertation sec. 2.3 (units mm, radians):

- Mirror frame (sec. 2.3.3): origin at the focus O_m, z along the mirror axis
  from the camera towards the mirror. Mirror surface (eq. 2.19):
  z = -c + b sqrt(1 + r^2 / a^2), c = sqrt(a^2 + b^2), from the tip (z = b - c)
  up to the rim r = m at height h above the tip, i.e. the base plane
  z = d = b + h - c.
- Base frame: origin at the centre of the mirror's base circle, axes parallel to
  the mirror frame's: p_mirror = p_base + (0, 0, d) (eq. 2.15).
- Camera frame (eqs. 2.4-2.5): origin at the lens centre O_c, z the optical axis
  (towards the mirror), image plane z = f; x along image u (pixel columns), y
  along image v (pixel rows, downwards).
- Pose: R = ``pose.R()`` (``omnidev.nonsvp.model``: Rz(tilt) Ry(yaw) Rx(pitch),
  the rotation of eq. 2.4, base -> camera directions). Eq. 2.13 is the
  definition of the pose, read as omnidev.nonsvp.model reads it: x_b = R' x_c - T
  with R' = R^T (reversing the signs *and* the order of the three rotations), so
  the lens centre is C = (-T_x, -T_y, -T_z + d) in the mirror frame (eq. 2.16)
  and camera directions map to mirror directions by R^T (``convention="eq2.13"``,
  the default). ``convention="eq2.4"`` reads T as eq. 2.4's (Tsai's) translation
  instead, p_camera = R p_base + T, i.e. C = -R^T T + (0, 0, d); with the
  dissertation's numbers the two lens centres differ by about 3 mm. With R = I
  and T = (0, 0, b + h + c) both put the lens centre at the second focus
  (0, 0, -2c): the SVP camera of eq. 2.1.
- Pixels (eqs. 2.9-2.11, 2.8): u_d = (u_f - C_x) / S_x, v_d = (v_f - C_y) / S_y
  (mm on the sensor), S = image size / sensor size, (C_x, C_y) the lens' centre
  (when the lens gives none: ((w - 1) / 2, (h - 1) / 2), eq. 2.10's w/2, h/2
  counted from pixel corners); ideal u = (1 - kappa r_d^2) u_d
  (eq. 2.8; eq. 2.12 writes the opposite sign, 1 + kappa r^2: the two agree at
  kappa = 0, the dissertation's value). Pixel centres are integers, the top-left
  pixel's centre (0, 0).

Truth views (sec. 2.5.1): a view plane point X is seen in the omni-image where
the light from X reaches the lens: via the mirror point M(X) at which
|X - M| + |M - C| is stationary (Fermat; the reflection law), found by Newton's
method from the SVP guess. The truth image at X is the scene along the ray
from M(X) through X (the first surface from the mirror on, so a wall in front of
the plane occludes it exactly as in the omni-image); a perfect unwarp of the
omni-image onto the plane equals it up to the pixel sampling of the two images.
Where a scene surface lies in the plane (the ground of the top view; the
textured room's walls and floor) the truth is the surface's own texture at X,
independent of the camera. See :func:`render_view_plane` and
:func:`view_plane_map`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.atomic import atomic_dir, check_output_dir
from omnidev.nonsvp.model import DISSERTATION_CAMERA, NonSvpCamera, Pose
from omnidev.sim.pseudo_target import GROUND_Z, SIDE_DISTANCE, NonSvpScene, make_scene
from omnidev.views import PlaneView, TopView, View

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Convention = Literal["eq2.13", "eq2.4"]

OUTSIDE = 10.0  # grey level of samples that miss the mirror
CHUNK = 1 << 19


def _row(v: FloatArray) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


@dataclass(frozen=True)
class TracedCamera:
    """All the ray tracer needs, plain numbers (mm, px, rad); see the module docstring.

    ``R`` is eq. 2.4's rotation (base -> camera), ``T`` its translation (mm);
    ``center_px`` is (C_x, C_y) and ``scale`` is (S_x, S_y) in px/mm.
    """

    a: float
    b: float
    h: float
    m: float
    f: float
    size: tuple[int, int]
    scale: tuple[float, float]
    center_px: tuple[float, float]
    kappa: float
    R: tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]
    T: tuple[float, float, float]
    convention: Convention = "eq2.13"

    @property
    def c(self) -> float:
        return math.hypot(self.a, self.b)

    @property
    def d(self) -> float:
        """Height of the base plane above O_m: b + h - c (mm)."""
        return self.b + self.h - self.c

    @classmethod
    def from_camera(
        cls, cam: Any, size: tuple[int, int] | None = None, convention: Convention = "eq2.13"
    ) -> TracedCamera:
        """Read a ``NonSvpCamera`` (mirror, lens, pose); ``size`` re-samples the same sensor."""
        mirror, lens, pose = cam.mirror, cam.lens, cam.pose
        a, b = float(mirror.a), float(mirror.b)
        c = float(getattr(mirror, "c", math.hypot(a, b)))
        if not math.isclose(c * c, a * a + b * b, rel_tol=1e-9):
            raise ValueError(f"mirror c = {c} but sqrt(a^2 + b^2) = {math.hypot(a, b)}")
        lw, lh = (int(v) for v in lens.size)
        w, h = size if size is not None else (lw, lh)
        ws, hs = (float(v) for v in lens.sensor)
        center = getattr(lens, "center", None)
        if center is None:
            cpx = ((w - 1) / 2.0, (h - 1) / 2.0)
        else:  # the same sensor point at another resolution
            cpx = ((float(center[0]) + 0.5) * w / lw - 0.5, (float(center[1]) + 0.5) * h / lh - 0.5)
        rot = np.asarray(pose.R(), np.float64)
        return cls(
            a,
            b,
            float(mirror.h),
            float(mirror.m),
            float(lens.f),
            (int(w), int(h)),
            (w / ws, h / hs),
            cpx,
            float(getattr(lens, "kappa", 0.0)),
            (_row(rot[0]), _row(rot[1]), _row(rot[2])),
            (float(pose.T[0]), float(pose.T[1]), float(pose.T[2])),
            convention,
        )


def camera_in_mirror(tc: TracedCamera) -> tuple[FloatArray, FloatArray]:
    """Lens centre C (3,) and camera-to-mirror rotation Q (3, 3): p_mirror = Q p_camera + C.

    Q = R^T in both conventions; ``eq2.13``: C = (-T_x, -T_y, -T_z + d) (eq. 2.16);
    ``eq2.4``: C = -R^T T + (0, 0, d) (T read as eq. 2.4's translation).
    """
    R = np.asarray(tc.R, np.float64)
    T = np.asarray(tc.T, np.float64)
    up = np.array([0.0, 0.0, tc.d])
    if tc.convention == "eq2.13":
        return -T + up, R.T.copy()
    if tc.convention == "eq2.4":
        return -R.T @ T + up, R.T.copy()
    raise ValueError(f"unknown pose convention {tc.convention!r} (eq2.13, eq2.4)")


def pixel_rays(tc: TracedCamera, uf: FloatArray, vf: FloatArray) -> FloatArray:
    """Unit directions (N, 3) in the mirror frame of the rays through pixels (u_f, v_f)."""
    ud = (uf - tc.center_px[0]) / tc.scale[0]
    vd = (vf - tc.center_px[1]) / tc.scale[1]
    k = 1.0 - tc.kappa * (ud * ud + vd * vd)
    dc = np.stack([k * ud, k * vd, np.full_like(ud, tc.f)], -1)
    _, Q = camera_in_mirror(tc)
    d = dc @ Q.T
    return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True), np.float64)


def trace_mirror(
    tc: TracedCamera, origin: FloatArray, dirs: FloatArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """First hit of rays ``origin + t dirs`` with the mirror sheet (mirror frame, mm).

    The sheet is (z + c)^2 / b^2 - (x^2 + y^2) / a^2 = 1 with z + c > 0; the hit
    counts when r <= m. Returns points (N, 3), unit outward normals (N, 3)
    (pointing away from O_m, towards the camera side) and the hit mask.
    """
    a2, b2, c = tc.a**2, tc.b**2, tc.c
    o = np.broadcast_to(np.asarray(origin, np.float64), dirs.shape)
    ox, oy, oz = o[:, 0], o[:, 1], o[:, 2] + c
    dx, dy, dz = dirs[:, 0], dirs[:, 1], dirs[:, 2]
    A = dz * dz / b2 - (dx * dx + dy * dy) / a2
    B = 2.0 * (oz * dz / b2 - (ox * dx + oy * dy) / a2)
    Cq = oz * oz / b2 - (ox * ox + oy * oy) / a2 - 1.0
    disc = B * B - 4 * A * Cq
    ok = disc >= 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        q = -0.5 * (B + np.copysign(sq, B))
        t1, t2 = q / A, Cq / q
    best = np.full(len(dirs), np.inf)
    for t in (t1, t2):
        zc = oz + t * dz
        good = ok & np.isfinite(t) & (t > 1e-9) & (zc > 0)
        best = np.where(good & (t < best), t, best)
    hit = np.isfinite(best)
    tt = np.where(hit, best, 0.0)
    p = o + tt[:, None] * dirs
    hit &= (p[:, 0] ** 2 + p[:, 1] ** 2) <= tc.m**2
    n = np.stack([p[:, 0] / a2, p[:, 1] / a2, -(p[:, 2] + c) / b2], -1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return p, n, hit


def reflect(d: FloatArray, n: FloatArray) -> FloatArray:
    """r = d - 2 (d . n) n for (N, 3) directions and unit normals."""
    return np.asarray(d - 2.0 * np.sum(d * n, axis=1, keepdims=True) * n, np.float64)


def _shade_pixels(
    tc: TracedCamera, scene: NonSvpScene, uf: FloatArray, vf: FloatArray
) -> tuple[FloatArray, BoolArray]:
    C, _ = camera_in_mirror(tc)
    out = np.full((len(uf), 3), OUTSIDE)
    hit_all = np.zeros(len(uf), bool)
    for i in range(0, len(uf), CHUNK):
        sl = slice(i, i + CHUNK)
        d = pixel_rays(tc, uf[sl], vf[sl])
        p, n, hit = trace_mirror(tc, C, d)
        if np.any(hit):
            out[sl][hit] = scene.shade(p[hit], reflect(d[hit], n[hit]))
        hit_all[sl] = hit
    return out, hit_all


def render_omni(
    cam: Any,
    scene: NonSvpScene,
    *,
    size: tuple[int, int] | None = None,
    supersample: int = 3,
    seed: int = 0,
    noise_sigma: float = 0.0,
    convention: Convention = "eq2.13",
) -> tuple[NDArray[np.uint8], BoolArray]:
    """The omni-image (H, W, 3) BGR uint8 and the (H, W) mask of pixels that see the mirror.

    ``cam`` is a ``NonSvpCamera`` (or a :class:`TracedCamera`); ``size`` (W, H)
    re-samples its sensor at another resolution. Each pixel is the mean of
    supersample^2 samples on a regular grid inside it; samples that miss the
    mirror are :data:`OUTSIDE` grey. The mask is True where every sample hits the
    mirror within its rim. ``noise_sigma`` adds Gaussian noise from ``seed``.
    """
    tc = cam if isinstance(cam, TracedCamera) else TracedCamera.from_camera(cam, size, convention)
    w, h = tc.size
    n = int(supersample)
    offs = (np.arange(n) + 0.5) / n - 0.5
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
    acc = np.zeros((h * w, 3))
    seen = np.ones(h * w, bool)
    for dy in offs:
        for dx in offs:
            col, hit = _shade_pixels(tc, scene, (uu + dx).ravel(), (vv + dy).ravel())
            acc += col
            seen &= hit
    img = acc.reshape(h, w, 3) / (n * n)
    if noise_sigma > 0:
        img += np.random.default_rng(seed).normal(0.0, noise_sigma, img.shape)
    return np.clip(img + 0.5, 0, 255).astype(np.uint8), seen.reshape(h, w)


# ---- truth views -----------------------------------------------------------------


def _mirror_z(tc: TracedCamera, x: FloatArray, y: FloatArray) -> FloatArray:
    return np.asarray(-tc.c + tc.b * np.sqrt(1.0 + (x * x + y * y) / tc.a**2), np.float64)


def _fermat_gradient(
    tc: TracedCamera, C: FloatArray, X: FloatArray, x: FloatArray, y: FloatArray
) -> FloatArray:
    """d(|X - M| + |C - M|)/d(x, y) for M = (x, y, z(x, y)) on the sheet, (N, 2)."""
    z = _mirror_z(tc, x, y)
    M = np.stack([x, y, z], -1)
    e1 = X - M
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = C - M
    e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
    s = e1 + e2
    k = tc.b**2 / (tc.a**2 * (z + tc.c))  # dz/dx = k x, dz/dy = k y
    gx = -(s[:, 0] + s[:, 2] * k * x)
    gy = -(s[:, 1] + s[:, 2] * k * y)
    return np.stack([gx, gy], -1)


def mirror_points_towards(
    tc: TracedCamera, points: FloatArray, *, iterations: int = 40
) -> tuple[FloatArray, BoolArray]:
    """Mirror points M (N, 3) that reflect light from ``points`` (N, 3) into the lens centre.

    Newton's method on the gradient of the optical path |X - M| + |M - C| over
    the sheet's (x, y), started at the SVP solution (where the line X -> O_m
    meets the sheet); central-difference Jacobian. The mask is False where it
    did not converge to 1e-9 mm or M lies outside the rim.
    """
    C, _ = camera_in_mirror(tc)
    X = np.asarray(points, np.float64).reshape(-1, 3)
    nrm = np.linalg.norm(X, axis=1)
    dz = X[:, 2] / nrm
    lam = tc.a**2 / (tc.b - tc.c * dz)
    x = lam * X[:, 0] / nrm
    y = lam * X[:, 1] / nrm
    eps = 1e-3
    conv = np.zeros(len(X), bool)
    todo = np.arange(len(X))
    for _ in range(iterations):
        Xt, xt, yt = X[todo], x[todo], y[todo]
        g = _fermat_gradient(tc, C, Xt, xt, yt)
        gxp = _fermat_gradient(tc, C, Xt, xt + eps, yt)
        gxm = _fermat_gradient(tc, C, Xt, xt - eps, yt)
        gyp = _fermat_gradient(tc, C, Xt, xt, yt + eps)
        gym = _fermat_gradient(tc, C, Xt, xt, yt - eps)
        j11 = (gxp[:, 0] - gxm[:, 0]) / (2 * eps)
        j21 = (gxp[:, 1] - gxm[:, 1]) / (2 * eps)
        j12 = (gyp[:, 0] - gym[:, 0]) / (2 * eps)
        j22 = (gyp[:, 1] - gym[:, 1]) / (2 * eps)
        det = j11 * j22 - j12 * j21
        with np.errstate(divide="ignore", invalid="ignore"):
            sx = (j22 * g[:, 0] - j12 * g[:, 1]) / det
            sy = (-j21 * g[:, 0] + j11 * g[:, 1]) / det
        bad = ~(np.isfinite(sx) & np.isfinite(sy))
        sx[bad] = 0.0
        sy[bad] = 0.0
        x[todo] = xt - sx
        y[todo] = yt - sy
        done = (np.hypot(sx, sy) < 1e-9) & ~bad
        conv[todo[done]] = True
        todo = todo[~done]
        if len(todo) == 0:
            break
    M = np.stack([x, y, _mirror_z(tc, x, y)], -1)
    ok = conv & (x * x + y * y <= tc.m**2)
    return M, ok


def project_to_pixels(tc: TracedCamera, points: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Computer image coordinates (N, 2) of mirror-frame points seen directly by the lens.

    Inverse of :func:`pixel_rays`: camera frame, ideal (u, v) = f (x, y) / z,
    distorted by solving u = (1 - kappa r_d^2) u_d (Newton on the radius), then
    eq. 2.9. The mask is z > 0 and the pixel inside the image (edges at -0.5
    and size - 0.5).
    """
    C, Q = camera_in_mirror(tc)
    pc = (np.asarray(points, np.float64) - C) @ Q  # Q^T (p - C)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = tc.f * pc[:, 0] / pc[:, 2]
        v = tc.f * pc[:, 1] / pc[:, 2]
    rho = np.hypot(u, v)
    rd = rho.copy()
    if tc.kappa != 0.0:
        for _ in range(30):
            rd = rd - (rd - tc.kappa * rd**3 - rho) / (1.0 - 3.0 * tc.kappa * rd**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(rho > 0, rd / rho, 1.0)
    uf = u * s * tc.scale[0] + tc.center_px[0]
    vf = v * s * tc.scale[1] + tc.center_px[1]
    w, h = tc.size
    ok = (pc[:, 2] > 0) & (uf >= -0.5) & (uf <= w - 0.5) & (vf >= -0.5) & (vf <= h - 0.5)
    return np.stack([uf, vf], -1), ok & np.isfinite(uf) & np.isfinite(vf)


def dissertation_planes(width: int = 320, height: int = 240) -> dict[str, View]:
    """The view planes of sec. 2.5.1 (mm, mirror frame), each ``width`` x ``height`` px.

    ``top``: :class:`TopView` of the 4 x 4 m plane z = -2000 (u -> +x, v -> -y).
    ``side_k`` (k = 0..3): :class:`PlaneView` of the vertical plane at sqrt(2) m
    from the z-axis spanning azimuths 90 k .. 90 (k + 1) degrees (2 sqrt(2) m
    wide), z from 0 (top row) to -2000 (bottom row), columns clockwise seen from
    above. Fig. 2.13 (a)-(d) are side_3, side_2, side_1, side_0.
    """
    planes: dict[str, View] = {"top": TopView(width, height, 4000.0, 4000.0, GROUND_Z)}
    for k in range(4):
        planes[f"side_{k}"] = PlaneView(
            width, height, SIDE_DISTANCE, 2 * SIDE_DISTANCE, GROUND_Z, 0.0, 45.0 + 90.0 * k
        )
    return planes


def _view_points(plane: View, factor: int) -> FloatArray:
    big = dataclasses.replace(
        plane,  # type: ignore[type-var]
        width=plane.width * factor,
        height=plane.height * factor,
    )
    return np.asarray(big.points(None), np.float64)


def view_plane_map(
    cam: Any, plane: View, *, size: tuple[int, int] | None = None, convention: Convention = "eq2.13"
) -> tuple[NDArray[np.float32], NDArray[np.float32], BoolArray]:
    """The exact omni pixel (map_x, map_y, float32 (H, W)) of each view pixel centre, and validity.

    Feed to ``cv2.remap(omni, map_x, map_y, cv2.INTER_LINEAR)``: the renderer's own
    mapping, the ceiling any unwarp can reach. Valid where the mirror point lies
    within the rim and its pixel inside the image.
    """
    tc = cam if isinstance(cam, TracedCamera) else TracedCamera.from_camera(cam, size, convention)
    pts = np.asarray(plane.points(None), np.float64)
    M, ok = mirror_points_towards(tc, pts.reshape(-1, 3))
    uv, ok2 = project_to_pixels(tc, M)
    shape = pts.shape[:2]
    return (
        uv[:, 0].reshape(shape).astype(np.float32),
        uv[:, 1].reshape(shape).astype(np.float32),
        (ok & ok2).reshape(shape),
    )


def render_view_plane(
    cam: Any,
    scene: NonSvpScene,
    plane: View,
    *,
    supersample: int = 3,
    size: tuple[int, int] | None = None,
    convention: Convention = "eq2.13",
) -> tuple[NDArray[np.uint8], BoolArray]:
    """The truth image of ``plane`` (H, W, 3) BGR uint8 and where the camera sees it.

    Each view pixel is the mean of supersample^2 sub-pixel points X on the plane;
    each X is coloured by the scene along the ray from its mirror point M(X)
    (:func:`mirror_points_towards`) through X. The mask is True where every
    sub-pixel point is seen (M within the rim, its pixel inside the image).
    """
    tc = cam if isinstance(cam, TracedCamera) else TracedCamera.from_camera(cam, size, convention)
    n = int(supersample)
    pts = _view_points(plane, n)
    flat = pts.reshape(-1, 3)
    col = np.empty((len(flat), 3))
    seen = np.empty(len(flat), bool)
    for i in range(0, len(flat), CHUNK):
        X = flat[i : i + CHUNK]
        M, ok = mirror_points_towards(tc, X)
        _, ok2 = project_to_pixels(tc, M)
        d = X - M
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        col[i : i + CHUNK] = scene.shade(M, d)
        seen[i : i + CHUNK] = ok & ok2
    H, W = plane.height, plane.width
    img = col.reshape(H, n, W, n, 3).mean(axis=(1, 3))
    mask = np.asarray(seen.reshape(H, n, W, n).all(axis=(1, 3)), np.bool_)
    return np.clip(img + 0.5, 0, 255).astype(np.uint8), mask


# ---- presets and fixtures --------------------------------------------------------

LARGE_POSE = Pose(pitch=0.04, yaw=-0.06, tilt=0.05, T=(-6.0, 4.0, 90.5))
"""A larger misalignment: lens 7.2 mm off the axis and 1.8 mm further away than
aligned, optical axis 4.1 degrees off (pitch 2.3, yaw -3.4, tilt 2.9 degrees).
With :data:`DISSERTATION_CAMERA`'s mirror at 1280x960 the rim images 370-380 px
from its centre (489, 474), at least 99 px inside the frame, and the incident
rays at the rim rise 1.4 to 9.7 degrees above the horizon, so every view of
:func:`dissertation_planes` is seen whole."""


def preset_camera(pose: str = "dissertation", size: tuple[int, int] = (640, 480)) -> NonSvpCamera:
    """:data:`DISSERTATION_CAMERA`'s mirror and lens at ``size`` px, with pose
    ``dissertation`` (its own), ``large`` (:data:`LARGE_POSE`) or ``svp`` (aligned)."""
    base = DISSERTATION_CAMERA
    lens = dataclasses.replace(base.lens, size=(int(size[0]), int(size[1])))
    if pose == "dissertation":
        return NonSvpCamera(base.mirror, lens, base.pose)
    if pose == "large":
        return NonSvpCamera(base.mirror, lens, LARGE_POSE)
    if pose == "svp":
        return NonSvpCamera.svp(base.mirror, lens)
    raise ValueError(f"unknown pose preset {pose!r} (dissertation, large, svp)")


def _plane_json(plane: View) -> dict[str, Any]:
    pts = np.asarray(plane.points(None), np.float64)
    return {
        "type": type(plane).__name__,
        **dataclasses.asdict(plane),  # type: ignore[call-overload]
        "units": "mm, mirror frame O_m",
        "pixel_centres": {
            "top_left": pts[0, 0].tolist(),
            "top_right": pts[0, -1].tolist(),
            "bottom_left": pts[-1, 0].tolist(),
        },
    }


def make_nonsvp_fixture(
    outdir: Path,
    cam: NonSvpCamera,
    scene: str = "textured",
    *,
    view_size: tuple[int, int] = (320, 240),
    supersample: int = 3,
    seed: int = 0,
    convention: Convention = "eq2.13",
    regenerate: str = "",
    force: bool = False,
) -> dict[str, Any]:
    """Render a fixture folder; returns what truth.json holds.

    Files: omni.png (the omni-image), mask.png (255 where every sample of the
    pixel sees the mirror), top.png and side_0..3.png (the truth views of
    :func:`dissertation_planes` at ``view_size``), top_mask.png and
    side_k_mask.png (255 where the camera sees the whole view pixel), truth.json
    (camera, pose convention, derived lens centre and rotation, scene, planes,
    the command that regenerates the folder).
    """
    outdir = Path(outdir)
    check_output_dir(outdir, force=force)
    the_scene = make_scene(scene, seed)
    tc = TracedCamera.from_camera(cam, None, convention)
    with atomic_dir(outdir, force=force) as tmp:
        img, mask = render_omni(tc, the_scene, supersample=supersample)
        cv2.imwrite(str(tmp / "omni.png"), img)
        cv2.imwrite(str(tmp / "mask.png"), mask.astype(np.uint8) * 255)
        views: dict[str, Any] = {}
        for name, plane in dissertation_planes(*view_size).items():
            vimg, vmask = render_view_plane(tc, the_scene, plane, supersample=supersample)
            cv2.imwrite(str(tmp / f"{name}.png"), vimg)
            cv2.imwrite(str(tmp / f"{name}_mask.png"), vmask.astype(np.uint8) * 255)
            views[name] = {
                "file": f"{name}.png",
                "mask": f"{name}_mask.png",
                "seen_fraction": float(vmask.mean()),
                **_plane_json(plane),
            }
            print(f"  {name}: seen {vmask.mean():.3f}", file=sys.stderr)
        C, Q = camera_in_mirror(tc)
        truth: dict[str, Any] = {
            "camera": cam.to_dict(),
            "pose_convention": convention,
            "derived": {
                "c_mm": tc.c,
                "d_mm": tc.d,
                "scale_px_per_mm": list(tc.scale),
                "principal_point_px": list(tc.center_px),
                "lens_centre_in_mirror_mm": C.tolist(),
                "rotation_camera_to_mirror": Q.tolist(),
            },
            "frames": "mirror frame O_m (origin at the focus, z from the camera towards the "
            "mirror), mm; see omnidev.sim.nonsvp",
            "scene": the_scene.describe(),
            "omni": {
                "file": "omni.png",
                "mask": "mask.png",
                "size": list(tc.size),
                "supersample": supersample,
                "outside_grey": OUTSIDE,
                "mirror_fraction": float(mask.mean()),
            },
            "views": views,
            "truth_definition": "view pixel = mean over supersample^2 plane points X of the "
            "scene colour along the ray from the mirror point M(X) (which reflects X into the "
            "lens centre) through X; omnidev.sim.nonsvp.view_plane_map gives the exact omni "
            "pixel of each view pixel centre",
            "regenerate": regenerate,
        }
        (tmp / "truth.json").write_text(json.dumps(truth, indent=2) + "\n")
    return truth
