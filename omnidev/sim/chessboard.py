"""Chessboard and ChArUco calibration sequences seen through a fisheye lens, with exact truth.

A view is rendered by inverse mapping: every pixel is unprojected through the lens to a ray in
the optical frame (OpenCV's camera frame: x right, y down, z along the optical axis), the ray
is intersected with the board plane, and the board is sampled there. Each pixel is the mean of
``supersample**2`` samples spread evenly over its footprint (antialiasing); the board
coordinates of a sample are interpolated bilinearly between the exact intersections at the
pixel's four corners, which is exact to second order in the pixel size. A chessboard is sampled
analytically, a ChArUco board from the image ``cv2.aruco.CharucoBoard.generateImage`` draws.
A light Gaussian blur (the lens's point spread) and sensor noise follow.

The truth of every view: the board pose (``X_opt = R @ X_board + t``, mm; board frame of
:mod:`omnidev.fisheye.pattern`) and the exact pixel of every inner corner (``lens.project``).
Poses are drawn from a seed so that the boards cover the image out to its periphery, at varied
tilts, with every point of the board (quiet zone included) inside the image and within
``max_angle_deg`` of the optical axis.

Any lens with ``project`` / ``unproject`` (an :class:`omnidev.fisheye.models.LensModel`) works.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, TypedDict

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.fisheye.pattern import Pattern

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Image = NDArray[np.uint8]

BLACK = 25.0  # grey level of a black square
WHITE = 230.0  # grey level of a white square and of the quiet zone
BACKGROUND = 105.0  # grey level of the wall behind the board
OUTSIDE = 0.0  # grey level where the lens sees nothing


class Lens(Protocol):
    """What the renderer needs of a lens model (optical frame, pixels)."""

    def project(self, xyz: FloatArray) -> tuple[FloatArray, BoolArray]: ...

    def unproject(self, uv: FloatArray) -> tuple[FloatArray, BoolArray]: ...


@dataclass(frozen=True)
class BoardView:
    """One view's truth.

    Attributes:
        rotation: (3, 3) board -> optical frame, ``X_opt = rotation @ X_board + translation``.
        translation: (3,) mm.
        corners_uv: (N, 2) exact pixel of every inner corner, in the pattern's id order.
    """

    rotation: FloatArray
    translation: FloatArray
    corners_uv: FloatArray

    @property
    def rvec(self) -> FloatArray:
        """Rodrigues vector of :attr:`rotation` (rad)."""
        r, _ = cv2.Rodrigues(self.rotation)
        return np.asarray(r, np.float64).ravel()


@dataclass(frozen=True)
class BoardSequence:
    """A rendered calibration sequence and its truth.

    ``images`` are (H, W) uint8 grey images (empty when rendered without images).
    """

    lens: Lens
    image_size: tuple[int, int]
    pattern: Pattern
    views: tuple[BoardView, ...]
    images: tuple[Image, ...] = field(default=(), repr=False)

    def noisy_corners(self, sigma_px: float, *, seed: int = 0) -> list[FloatArray]:
        """The true corners plus Gaussian noise of ``sigma_px`` on each of u and v."""
        rng = np.random.default_rng(seed)
        return [v.corners_uv + rng.normal(0.0, sigma_px, v.corners_uv.shape) for v in self.views]


# ---------------------------------------------------------------- poses


def _look_rotation(d: FloatArray) -> FloatArray:
    """The smallest rotation taking +z to unit vector ``d``."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, d)
    s = float(np.linalg.norm(axis))
    c = float(np.dot(z, d))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    r, _ = cv2.Rodrigues(axis / s * math.atan2(s, c))
    return np.asarray(r, np.float64)


def _rot(axis: int, angle: float) -> FloatArray:
    v = np.zeros(3)
    v[axis] = angle
    r, _ = cv2.Rodrigues(v)
    return np.asarray(r, np.float64)


def _outline(pattern: Pattern, quiet: float, n: int = 24) -> FloatArray:
    """(4n, 3) points on the outer edge of the printed board (squares + quiet zone), mm."""
    w, h = pattern.size_mm()
    q = quiet * pattern.square_mm
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    x0, x1, y0, y1 = -q, w + q, -q, h + q
    pts = np.concatenate(
        [
            np.stack([x0 + (x1 - x0) * t, np.full(n, y0)], -1),
            np.stack([np.full(n, x1), y0 + (y1 - y0) * t], -1),
            np.stack([x1 - (x1 - x0) * t, np.full(n, y1)], -1),
            np.stack([np.full(n, x0), y1 - (y1 - y0) * t], -1),
        ]
    )
    return np.concatenate([pts, np.zeros((len(pts), 1))], -1)


def _pose_ok(
    lens: Lens,
    image_size: tuple[int, int],
    pattern: Pattern,
    rot: FloatArray,
    t: FloatArray,
    *,
    quiet: float,
    max_angle: float,
    margin_px: float,
    min_angle: float = 0.0,
    min_spacing_px: float,
    max_view_angle: float,
) -> bool:
    w, h = image_size
    pts = np.concatenate([_outline(pattern, quiet), pattern.object_points()])
    cam = pts @ rot.T + t
    ang = np.arctan2(np.hypot(cam[:, 0], cam[:, 1]), cam[:, 2])
    if np.any(ang > max_angle) or np.any(ang < min_angle):
        return False
    # the camera sees the printed side: board +z points away from the camera
    n = rot[:, 2]
    sight = cam / np.linalg.norm(cam, axis=1, keepdims=True)
    if np.any(sight @ n < math.cos(max_view_angle)):
        return False
    uv, ok = lens.project(cam)
    inside = (
        (uv[:, 0] >= margin_px - 0.5)
        & (uv[:, 0] <= w - 0.5 - margin_px)
        & (uv[:, 1] >= margin_px - 0.5)
        & (uv[:, 1] <= h - 0.5 - margin_px)
    )
    if not np.all(ok & inside):
        return False
    cx, cy = pattern.inner
    grid = uv[-pattern.n_corners :].reshape(cy, cx, 2)
    du = np.linalg.norm(np.diff(grid, axis=1), axis=-1)
    dv = np.linalg.norm(np.diff(grid, axis=0), axis=-1)
    return bool(min(du.min(), dv.min()) >= min_spacing_px)


def board_poses(
    lens: Lens,
    image_size: tuple[int, int],
    pattern: Pattern,
    n_views: int,
    *,
    seed: int = 0,
    max_angle_deg: float = 80.0,
    min_angle_deg: float = 0.0,
    max_tilt_deg: float = 40.0,
    max_view_angle_deg: float = 65.0,
    board_angle_deg: tuple[float, float] = (55.0, 95.0),
    margin_px: float = 6.0,
    min_spacing_px: float = 11.0,
    quiet: float = 1.0,
) -> list[tuple[FloatArray, FloatArray]]:
    """Board poses ``(R, t)`` (board -> optical frame, mm) covering the image.

    The board centre's angle from the optical axis runs evenly from the smallest that keeps
    the whole board beyond ``min_angle_deg`` (0 by default; a mirror camera images nothing
    inside its cut-off circle) to the largest that keeps it within ``max_angle_deg`` (so
    about half the views reach the periphery), its
    azimuth turns by the golden angle from view to view; the board subtends
    ``board_angle_deg`` (a random value in that range), is tilted about both board axes by up
    to ``max_tilt_deg`` from facing the camera, and rolled freely. Each pose keeps every point
    of the printed board (``quiet`` squares of white margin included) ``margin_px`` inside the
    image, seen at most ``max_view_angle_deg`` off the board normal, with inner corners at
    least ``min_spacing_px`` apart. A draw that fails is redrawn (closer to the axis if needed).
    """
    rng = np.random.default_rng(seed)
    w_mm, h_mm = pattern.size_mm()
    diag = math.hypot(w_mm, h_mm) + 2 * quiet * pattern.square_mm
    centre = np.array([w_mm / 2, h_mm / 2, 0.0])
    max_angle = math.radians(max_angle_deg)
    min_angle = math.radians(min_angle_deg)
    golden = math.pi * (3.0 - math.sqrt(5.0))
    phase = rng.uniform(0, 2 * math.pi)
    poses: list[tuple[FloatArray, FloatArray]] = []
    for k in range(n_views):
        frac = k / max(n_views - 1, 1)
        azimuth = phase + k * golden
        for attempt in range(400):
            shrink = 1.0 - attempt / 400
            size = math.radians(rng.uniform(*board_angle_deg))
            lo = min_angle + 0.45 * size if min_angle > 0 else 0.0
            hi = max(max_angle - 0.45 * size, lo)
            # a failed draw moves toward the axis, or with min_angle_deg toward mid-range
            mid = 0.5 if min_angle > 0 else 0.0
            alpha = lo + (hi - lo) * (frac * shrink + mid * (1 - shrink)) + rng.normal(0, 0.03)
            alpha = min(max(alpha, 0.0), max_angle)
            az = azimuth + rng.normal(0, 0.15)
            d = np.array(
                [math.sin(alpha) * math.cos(az), math.sin(alpha) * math.sin(az), math.cos(alpha)]
            )
            rot = (
                _look_rotation(d)
                @ _rot(2, rng.uniform(-math.pi, math.pi))
                @ _rot(0, math.radians(rng.uniform(-max_tilt_deg, max_tilt_deg)))
                @ _rot(1, math.radians(rng.uniform(-max_tilt_deg, max_tilt_deg)))
            )
            dist = diag / (2 * math.tan(size / 2))
            t = dist * d - rot @ centre
            if _pose_ok(
                lens,
                image_size,
                pattern,
                rot,
                t,
                quiet=quiet,
                max_angle=max_angle,
                min_angle=min_angle,
                margin_px=margin_px,
                min_spacing_px=min_spacing_px,
                max_view_angle=math.radians(max_view_angle_deg),
            ):
                poses.append((rot, t))
                break
        else:
            raise ValueError(f"no valid board pose for view {k} (image too small for the board?)")
    return poses


# ---------------------------------------------------------------- rendering


@dataclass(frozen=True)
class _Rays:
    """Unit rays through the pixel corners, (H+1, W+1, 3), and their validity."""

    dirs: FloatArray
    valid: BoolArray
    centre_valid: BoolArray  # (H, W): the lens sees the pixel centre


def _pixel_corner_rays(lens: Lens, image_size: tuple[int, int]) -> _Rays:
    w, h = image_size
    vv, uu = np.mgrid[0 : h + 1, 0 : w + 1].astype(np.float64)
    dirs, valid = lens.unproject(np.stack([uu - 0.5, vv - 0.5], -1))
    vc, uc = np.mgrid[0:h, 0:w].astype(np.float64)
    _, cvalid = lens.unproject(np.stack([uc, vc], -1))
    dirs = np.where(valid[..., None], dirs, np.nan)
    return _Rays(np.asarray(dirs, np.float64), np.asarray(valid, bool), np.asarray(cvalid, bool))


def _board_coords(rays: _Rays, rot: FloatArray, t: FloatArray) -> FloatArray:
    """(H+1, W+1, 2) board x, y (mm) where each corner ray meets the board plane; NaN if never."""
    n = rot[:, 2]
    denom = rays.dirs @ n
    with np.errstate(invalid="ignore", divide="ignore"):
        lam = float(n @ t) / denom
        p = rays.dirs * lam[..., None] - t
    xy = p @ rot[:, :2]
    bad = ~(lam > 0) | ~np.isfinite(lam)
    xy[bad] = np.nan
    return np.asarray(xy, np.float64)


def _sample_chessboard(pattern: Pattern, x: FloatArray, y: FloatArray, quiet: float) -> FloatArray:
    s = pattern.square_mm
    w, h = pattern.size_mm()
    q = quiet * s
    with np.errstate(invalid="ignore"):
        on_board = (x >= 0) & (x < w) & (y >= 0) & (y < h)
        in_quiet = (x >= -q) & (x < w + q) & (y >= -q) & (y < h + q)
        parity = (np.floor(np.nan_to_num(x / s)) + np.floor(np.nan_to_num(y / s))) % 2
    out = np.full(x.shape, BACKGROUND)
    out[in_quiet] = WHITE
    out[on_board] = np.where(parity[on_board] == 0, BLACK, WHITE)
    return out


class _CharucoTexture:
    """The board image of ``cv2.aruco`` sampled bilinearly at board coordinates (mm)."""

    def __init__(self, pattern: Pattern, quiet: float, px_per_square: int = 64) -> None:
        sx, sy = pattern.squares
        self.margin = round(quiet * px_per_square)
        self.scale = px_per_square / pattern.square_mm
        size = (sx * px_per_square + 2 * self.margin, sy * px_per_square + 2 * self.margin)
        img = pattern.charuco_board().generateImage(size, marginSize=self.margin, borderBits=1)
        grey = np.asarray(img, np.float32) / 255.0
        self.texture = (BLACK + (WHITE - BLACK) * grey).astype(np.float32)

    def sample(self, x: FloatArray, y: FloatArray) -> FloatArray:
        mx = np.nan_to_num(self.margin + x * self.scale - 0.5, nan=-1e5).astype(np.float32)
        my = np.nan_to_num(self.margin + y * self.scale - 0.5, nan=-1e5).astype(np.float32)
        mx = np.clip(mx, -1e5, 1e5)
        my = np.clip(my, -1e5, 1e5)
        out = cv2.remap(
            self.texture,
            mx,
            my,
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=BACKGROUND,
        )
        return np.asarray(out, np.float64)


def render_board_view(
    lens: Lens,
    image_size: tuple[int, int],
    pattern: Pattern,
    rotation: FloatArray,
    translation: FloatArray,
    *,
    supersample: int = 4,
    blur_sigma_px: float = 0.6,
    noise_sigma: float = 1.5,
    quiet: float = 1.0,
    seed: int = 0,
    _rays: _Rays | None = None,
    _texture: _CharucoTexture | None = None,
) -> Image:
    """One (H, W) uint8 grey image of the board at pose ``(rotation, translation)``.

    ``supersample**2`` samples per pixel; then a Gaussian blur of ``blur_sigma_px`` and
    Gaussian sensor noise of ``noise_sigma`` grey levels (seeded). Pixels the lens cannot see
    are black.
    """
    w, h = image_size
    rays = _rays if _rays is not None else _pixel_corner_rays(lens, image_size)
    xy = _board_coords(rays, np.asarray(rotation, np.float64), np.asarray(translation, np.float64))
    texture = _texture
    if pattern.kind == "charuco" and texture is None:
        texture = _CharucoTexture(pattern, quiet)
    n = supersample
    offs = (np.arange(n) + 0.5) / n
    x00, x10, x01, x11 = xy[:-1, :-1], xy[:-1, 1:], xy[1:, :-1], xy[1:, 1:]
    acc = np.zeros((h, w))
    for b in offs:
        for a in offs:
            p = (1 - a) * (1 - b) * x00 + a * (1 - b) * x10 + (1 - a) * b * x01 + a * b * x11
            if texture is None:
                acc += _sample_chessboard(pattern, p[..., 0], p[..., 1], quiet)
            else:
                acc += texture.sample(p[..., 0], p[..., 1])
    img = acc / (n * n)
    img[~rays.centre_valid] = OUTSIDE
    if blur_sigma_px > 0:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), blur_sigma_px), np.float64)
    if noise_sigma > 0:
        img = img + np.random.default_rng(seed).normal(0.0, noise_sigma, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def project_corners(
    lens: Lens, pattern: Pattern, rotation: FloatArray, translation: FloatArray
) -> FloatArray:
    """(N, 2) exact pixels of the pattern's inner corners at a pose."""
    cam = pattern.object_points() @ np.asarray(rotation).T + np.asarray(translation)
    uv, _ = lens.project(cam)
    return np.asarray(uv, np.float64)


def render_sequence(
    lens: Lens,
    image_size: tuple[int, int],
    pattern: Pattern,
    n_views: int = 14,
    *,
    seed: int = 0,
    images: bool = True,
    supersample: int = 4,
    blur_sigma_px: float = 0.6,
    noise_sigma: float = 1.5,
    poses: Sequence[tuple[FloatArray, FloatArray]] | None = None,
    **pose_options: float | tuple[float, float],
) -> BoardSequence:
    """A calibration sequence: poses from :func:`board_poses` (or ``poses``), truth, images.

    ``pose_options`` go to :func:`board_poses` (e.g. ``max_angle_deg``; the test lenses':
    :func:`default_pose_options`). With
    ``images=False`` only the truth is computed (fast; for point-level tests).
    """
    if poses is None:
        poses = board_poses(lens, image_size, pattern, n_views, seed=seed, **pose_options)  # type: ignore[arg-type]
    views = tuple(BoardView(rot, t, project_corners(lens, pattern, rot, t)) for rot, t in poses)
    rendered: tuple[Image, ...] = ()
    if images:
        q = pose_options.get("quiet", 1.0)
        quiet = 1.0 if isinstance(q, tuple) else float(q)
        rays = _pixel_corner_rays(lens, image_size)
        texture = _CharucoTexture(pattern, quiet) if pattern.kind == "charuco" else None
        rendered = tuple(
            render_board_view(
                lens,
                image_size,
                pattern,
                v.rotation,
                v.translation,
                supersample=supersample,
                blur_sigma_px=blur_sigma_px,
                noise_sigma=noise_sigma,
                quiet=quiet,
                seed=seed * 1000 + i,
                _rays=rays,
                _texture=texture,
            )
            for i, v in enumerate(views)
        )
    return BoardSequence(lens, image_size, pattern, views, rendered)


def default_lens(model: str, image_size: tuple[int, int] = (800, 800)) -> Lens:
    """The test lenses: a ~200-degree-class KB4, a Mei lens or a catadioptric Scaramuzza
    lens, scaled to ``image_size``.

    At 800 x 800: KB4 fx 290, fy 289.3, centre (402.1, 397.6), k (0.012, -0.006, 0.0021,
    -0.0004); Mei fx 455, fy 454.1, centre (398.9, 402.4), xi 0.95, k1 -0.03, k2 0.006,
    p1 0.0004, p2 -0.0003; Scaramuzza: the OCamCalib polynomial of a mirror camera (the
    shape of the KaidanOmni calibration, scaled: 67 degrees off the axis at 167 px from the
    centre, 140 degrees at 400 px, i.e. up to 50 degrees beyond the lens plane),
    ss = (-123.0, 0, 1.404e-3, 7.05e-7, 1.29e-8), centre (row, column) (402.7, 397.4), affine
    c 1.0012, d = e = 0.0004. Focal lengths scale with
    the smaller side, the centre keeps its offset from the image centre (scaled).
    """
    from omnidev.fisheye.models import KannalaBrandt, Scaramuzza, Unified

    w, h = image_size
    s = min(w, h) / 800.0
    mu, mv = (w - 1) / 2, (h - 1) / 2
    if model == "kb4":
        return KannalaBrandt(
            290.0 * s, 289.3 * s, mu + 2.6 * s, mv - 1.9 * s, (0.012, -0.006, 0.0021, -0.0004)
        )
    if model == "mei":
        return Unified(
            455.0 * s, 454.1 * s, mu - 0.6 * s, mv + 2.9 * s, 0.95,
            k1=-0.03, k2=0.006, p1=0.0004, p2=-0.0003,
        )  # fmt: skip
    if model == "scaramuzza":
        ss = (-123.0 * s, 0.0, 1.404e-3 / s, 7.05e-7 / s**2, 1.29e-8 / s**3)
        return Scaramuzza(ss, xc=mv + 3.2 * s, yc=mu - 2.1 * s, c=1.0012, d=0.0004, e=0.0004)
    raise ValueError(f"no default lens for model {model!r}: kb4, mei or scaramuzza")


class PoseOptions(TypedDict, total=False):
    """Options of :func:`board_poses` that :func:`default_pose_options` sets."""

    max_angle_deg: float
    min_angle_deg: float
    board_angle_deg: tuple[float, float]
    min_spacing_px: float


def default_pose_options(model: str) -> PoseOptions:
    """:func:`board_poses` options for the test lens of ``model`` (see :func:`default_lens`).

    KB4: the defaults (corners within 80 degrees of the axis: cv2.fisheye initialises each
    pose on the pinhole-normalised plane, which a board beyond 90 degrees cannot reach).
    Mei: corners up to 100 degrees off the axis (the image corners of the Mei test lens are
    at 100.6 degrees, its inscribed circle at 81) and boards subtending 30 to 95 degrees, so
    far, small boards reach the image border as a user is told to place them: the corners
    reach 0.97 of the inscribed radius with 24 views (0.78 with the KB4 options).
    Scaramuzza (the mirror lens): boards between 70 and 135 degrees off the axis (the
    mirror's ring, as a catadioptric camera sees the room around it), subtending 25 to 60
    degrees, corners at least 6 px apart (the squeezed squares of a real mirror image:
    6 to 15 px on KaidanOmni).
    """
    if model == "scaramuzza":
        return {
            "min_angle_deg": 70.0,
            "max_angle_deg": 135.0,
            "board_angle_deg": (25.0, 60.0),
            "min_spacing_px": 6.0,
        }
    if model == "kb4":
        return {}
    if model == "mei":
        return {"max_angle_deg": 100.0, "board_angle_deg": (30.0, 95.0)}
    raise ValueError(f"no default pose options for model {model!r}: kb4, mei or scaramuzza")
