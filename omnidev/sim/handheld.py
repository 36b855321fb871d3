"""Randomized hand-held camera-mouse videos with per-frame truth (issue 13).

Each video is drawn from one seed (:func:`draw_video`) and rendered frame by frame
(:class:`HandheldRenderer`); nothing is shared between seeds except the code.

What a seed draws:

- the webcam: 320x240 to 1280x720, 50-85 degrees horizontal view, principal point off
  the centre by ~1.5 %, OpenCV distortion (k1 -0.35..0.05, k2, k3, p1, p2), 15-30 fps,
  global or rolling shutter (rows read out over 10-33 ms, as webcam sensors do),
  exposure 1/400-1/30 s;
- the monitor: screen 0.30-0.80 m wide, 16:9, 16:10, 4:3 or 21:9, a black, grey,
  silver or white bezel 4-60 mm wide per side, and the four landmark cards (a black
  disc 3-7 % of the screen width on a white square 1.35-2.2 discs wide) at offsets
  from the screen corners of one of several layouts (symmetric, asymmetric, per
  corner), overhanging the bezel where it is thin;
- what the screen shows (:mod:`omnidev.sim.handheld_textures`): desktops with windows
  and text, documents, dark themes, slides, photos, saturated colours, video; landmark
  look-alikes (black discs on white squares) on the screen and in the room;
- the room: a wall 0.15-1.5 m behind the screen with posters, frames and shelves; the
  light level and its gradient, the screen's brightness against the room (1-8x);
- the hand (:mod:`omnidev.sim.handheld_path`): distance, obliqueness to 45 degrees,
  roll to 30 degrees, sweeps with motion blur up to 5-25 px, excursions with 1, 2 or
  3-4 landmarks out of the picture, sway and tremor;
- the camera's processing: auto-exposure (gain following the scene with a lag),
  vignetting, white balance, defocus, shot and read noise, gamma 1.8-2.6, JPEG quality
  40-95 (MJPG webcams);
- the kind of video: ``normal`` (a monitor with landmarks), ``no-monitor`` (the room
  alone, maybe a few look-alikes) or ``lookalikes`` (look-alike cards in the room, four
  of them often on a rectangle the size and shape of the layout, no monitor).

Truth per frame (:meth:`HandheldRenderer.truth`): the screen point on the ray of the
image centre pixel ((W-1)/2, (H-1)/2) at the frame's time (the middle of the exposure of
the centre row), normalized as in :mod:`omnidev.sim.monitor` (screen pixel
``px = X / pitch - 0.5`` of a 1920x1080 screen, ``nx = px / 1919``); each landmark's
image position (distorted, at its own row's time under the rolling shutter), whether its
whole white square is in the picture, whether its centre is; the blur (px) of the
landmarks over the exposure; distance, view angle and roll.

World frame: that of :mod:`omnidev.sim.handcam` (metres; screen plane z = 0, lit area
[0, W] x [0, H], x right, y down, z into the screen; camera at z < 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.mouse.landmarks import LandmarkLayout
from omnidev.sim.handcam import HandCamera
from omnidev.sim.handheld_path import Trajectory, draw_path, look_at_many
from omnidev.sim.handheld_textures import (
    SCREEN_KINDS,
    lookalike,
    room_texture,
    screen_content,
    video_frame,
)

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]

KINDS = ("normal", "no-monitor", "lookalikes")
SIZES = ((320, 240), (640, 480), (640, 360), (800, 600), (960, 540), (1280, 720))
_SIZE_P = (0.25, 0.35, 0.1, 0.1, 0.1, 0.1)
SCREEN_PX = (1920, 1080)
_U16 = 65535.0 / 1.5  # monitor texture (uint16) value of radiance 1.0 (up to 1.5 fits)
_U8 = 255.0 / 1.5  # wall texture (uint8) value of radiance 1.0; _U16 / _U8 = 257


@dataclass(frozen=True)
class Monitor:
    """The monitor (metres): lit area ``screen_m``, bezel widths (left, top, right,
    bottom), bezel reflectance (BGR), the landmark cards' layout, the screen's
    brightness (radiance of its white), the card's white and the disc's black
    reflectance."""

    screen_m: tuple[float, float]
    bezel_m: tuple[float, float, float, float]
    bezel_refl: tuple[float, float, float]
    layout: LandmarkLayout
    screen_white: float
    card_white: float
    disc_black: float
    content_kind: str
    screen_lookalikes: int

    def landmark_centers_m(self) -> FloatArray:
        """(4, 3) landmark disc centres TL, TR, BR, BL on z = 0 (m)."""
        c = self.layout.landmark_centers_mm() / 1000.0
        return np.column_stack([c, np.zeros(4)])


@dataclass(frozen=True)
class Imaging:
    """Exposure and processing of the webcam (times in s, radiance linear)."""

    fps: float
    exposure_s: float
    readout_s: float
    ae_target: float  # mean linear level auto-exposure aims at
    ae_rate: float  # fraction of the log-gain error corrected per frame
    shot: float  # shot-noise variance per unit signal
    read: float  # read-noise sigma (linear, at gain 1)
    gamma: float
    white_balance: tuple[float, float, float]
    vignette: float  # relative fall-off at the image corner
    defocus_px: float  # Gaussian sigma
    jpeg_quality: int
    room_light: float  # radiance of a white (reflectance 1) surface at the screen centre
    light_gradient: tuple[float, float]  # relative change per metre in x and y


@dataclass(frozen=True)
class HandheldVideo:
    """Everything one seed draws (see the module docstring)."""

    seed: int
    kind: str
    frames: int
    camera: HandCamera
    imaging: Imaging
    path: Trajectory
    monitor: Monitor | None  # None for the no-monitor and look-alike kinds
    layout: LandmarkLayout  # what the tracker is given (the virtual one without a monitor)
    wall_z: float
    room_lookalikes: int
    lookalike_rect: bool
    max_blur_px: float
    dist_m: float

    def layout_dict(self) -> dict[str, Any]:
        """The landmark layout as ``omnidev mouse --layout`` reads it (mm)."""
        return self.layout.to_dict()

    def describe(self) -> dict[str, Any]:
        """The drawn parameters, JSON-ready (the per-frame truth is apart)."""
        cam = self.camera
        m = self.monitor
        return {
            "seed": self.seed,
            "kind": self.kind,
            "frames": self.frames,
            "fps": self.imaging.fps,
            "size": [cam.width, cam.height],
            "camera": {
                "fx": cam.fx,
                "fy": cam.fy,
                "cx": cam.cx,
                "cy": cam.cy,
                "distortion": cam.distortion().tolist(),
                "hfov_deg": math.degrees(2 * math.atan(cam.width / 2 / cam.fx)),
            },
            "imaging": {
                k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(self.imaging).items()
            },
            "monitor": None
            if m is None
            else {
                "screen_m": list(m.screen_m),
                "bezel_m": list(m.bezel_m),
                "content": m.content_kind,
                "screen_lookalikes": m.screen_lookalikes,
                "screen_to_card": m.screen_white / (m.card_white * self.imaging.room_light),
            },
            "layout": self.layout_dict(),
            "wall_z_m": self.wall_z,
            "room_lookalikes": self.room_lookalikes,
            "lookalike_rect": self.lookalike_rect,
            "max_blur_px": self.max_blur_px,
            "dist_m": self.dist_m,
            "segments": [[round(t, 3), k] for t, k in self.path.segments],
        }


def _draw_camera(rng: np.random.Generator, size: tuple[int, int]) -> HandCamera:
    w, h = size
    while True:
        hfov = float(rng.uniform(50, 85))
        fx = (w / 2) / math.tan(math.radians(hfov) / 2)
        k1 = float(rng.uniform(-0.35, 0.05)) * (0.5 + hfov / 85)
        k2 = float(rng.uniform(-0.05, 0.15))
        k3 = float(rng.uniform(-0.02, 0.02))
        cam = HandCamera(
            w,
            h,
            fx,
            fx * float(rng.uniform(0.995, 1.005)),
            (w - 1) / 2 + float(rng.normal(0, 0.015 * w)),
            (h - 1) / 2 + float(rng.normal(0, 0.015 * h)),
            k1,
            k2,
            float(rng.normal(0, 0.001)),
            float(rng.normal(0, 0.001)),
            k3,
        )
        # the radial polynomial must stay increasing well past the picture's corner
        rmax = 1.6 * math.hypot(w / 2, h / 2) / fx
        r = np.linspace(0, rmax, 200)
        r2 = r * r
        d = 1 + r2 * (3 * k1 + r2 * (5 * k2 + 7 * k3 * r2))
        if np.all(d > 0.2):
            return cam


def _draw_layout(
    rng: np.random.Generator, screen_m: tuple[float, float], bezel: tuple[float, ...]
) -> LandmarkLayout:
    W, H = screen_m
    disc = max(12.0, round(W * 1000 * float(rng.uniform(0.03, 0.07))))
    square = round(disc * float(rng.uniform(1.35, 2.2)))
    kind = rng.choice(["symmetric", "asymmetric", "per-corner"], p=[0.4, 0.35, 0.25])
    half = square / 2

    def off(b_mm: float) -> float:
        # centre on the bezel when it is wide enough, else the card overhangs it
        lo = half + 1.0
        hi = max(lo + 2.0, b_mm - half + 4.0, lo + 30.0 * float(rng.random()))
        return float(rng.uniform(lo, hi))

    bl, bt, br, bb = (1000 * b for b in bezel)
    if kind == "symmetric":
        m = off(min(bl, bt))
        mx = my = m
        offs = ((-mx, -my), (mx, -my), (mx, my), (-mx, my))
    elif kind == "asymmetric":
        mx, my = off(bl), off(bt)
        offs = ((-mx, -my), (mx, -my), (mx, my), (-mx, my))
    else:
        offs = ((-off(bl), -off(bt)), (off(br), -off(bt)), (off(br), off(bb)), (-off(bl), off(bb)))
    return LandmarkLayout(W * 1000, H * 1000, offs, float(disc), float(square))


def draw_video(
    seed: int,
    *,
    frames: int = 300,
    kind: str | None = None,
    size: tuple[int, int] | None = None,
) -> HandheldVideo:
    """Draw one video's world from ``seed`` (see the module docstring); ``kind`` and
    ``size`` override the drawn ones (the rest is drawn as if they had come out)."""
    rng = np.random.default_rng([seed, 1313])
    k = str(rng.choice(KINDS, p=[0.8, 0.1, 0.1]))
    s = SIZES[int(rng.choice(len(SIZES), p=_SIZE_P))]
    kind = kind or k
    size = size or s
    if kind not in KINDS:
        raise ValueError(f"unknown hand-held video kind {kind!r} ({', '.join(KINDS)})")
    cam = _draw_camera(rng, size)
    fps = float(rng.choice([30.0, 25.0, 15.0], p=[0.75, 0.1, 0.15]))
    W = float(rng.uniform(0.30, 0.80))
    aspect = float(rng.choice([16 / 9, 16 / 10, 4 / 3, 21 / 9], p=[0.6, 0.2, 0.12, 0.08]))
    screen_m = (W, W / aspect)
    bezel = (*(float(rng.uniform(0.004, 0.035)) for _ in range(3)), float(rng.uniform(0.004, 0.06)))
    layout = _draw_layout(rng, screen_m, bezel)
    # distance: the screen spans 25-65 % of the picture's width; landmark discs at
    # least 6 px across at the start and 4.5 px at the farthest (the method's envelope)
    frac = float(rng.uniform(0.25, 0.65))
    dist = W / (frac * cam.width / cam.fx)
    disc_m = layout.circle_diameter_mm / 1000
    if cam.fx * disc_m / dist < 6.0:
        dist = cam.fx * disc_m / 6.0
    dist_range = (0.7 * dist, min(1.35 * dist, cam.fx * disc_m / 4.5))
    exposure = min(float(math.exp(rng.uniform(math.log(1 / 400), math.log(1 / 30)))), 1 / fps)
    # a webcam sensor reads its rows out in 10-33 ms whatever the frame rate (a lower
    # rate adds blanking); never more than the frame time
    readout = 0.0 if rng.random() < 0.2 else min(float(rng.uniform(0.010, 0.033)), 0.95 / fps)
    max_blur = float(rng.uniform(5, 25))
    ratio = float(math.exp(rng.uniform(0.0, math.log(8.0))))  # screen white / card white
    card_white = float(rng.uniform(0.75, 0.92))
    screen_white = float(rng.uniform(0.6, 1.0))
    room_light = screen_white / (ratio * card_white)
    imaging = Imaging(
        fps=fps,
        exposure_s=exposure,
        readout_s=readout,
        ae_target=float(rng.uniform(0.12, 0.3)),
        ae_rate=float(rng.uniform(0.08, 0.4)),
        shot=float(rng.uniform(2e-4, 1.5e-3)),
        read=float(rng.uniform(5e-4, 3e-3)),
        gamma=float(rng.uniform(1.8, 2.6)),
        white_balance=tuple(float(v) for v in rng.uniform(0.85, 1.15, 3)),  # type: ignore[arg-type]
        vignette=float(rng.uniform(0.0, 0.45)),
        defocus_px=float(rng.uniform(0.0, 1.0)) * cam.width / 640,
        jpeg_quality=int(rng.integers(40, 96)),
        room_light=room_light,
        light_gradient=(float(rng.normal(0, 0.4)), float(rng.normal(0, 0.4))),
    )
    bz = rng.choice(["black", "grey", "silver", "white"], p=[0.6, 0.2, 0.12, 0.08])
    base = {"black": 0.035, "grey": 0.12, "silver": 0.4, "white": 0.75}[str(bz)]
    bezel_refl = tuple(float(base * v) for v in rng.uniform(0.9, 1.1, 3))
    content_kind = str(rng.choice(SCREEN_KINDS, p=[0.35, 0.12, 0.12, 0.12, 0.08, 0.08, 0.13]))
    screen_lookalikes = int(rng.integers(1, 5)) if rng.random() < 0.25 else 0
    monitor = (
        Monitor(
            screen_m,
            bezel,  # type: ignore[arg-type]
            bezel_refl,  # type: ignore[arg-type]
            layout,
            screen_white,
            card_white,
            float(rng.uniform(0.02, 0.06)),
            content_kind,
            screen_lookalikes,
        )
        if kind == "normal"
        else None
    )
    if kind == "lookalikes":
        room_lookalikes = int(rng.integers(4, 9))
        rect = bool(rng.random() < 0.6)
    elif kind == "no-monitor":
        room_lookalikes = int(rng.integers(0, 4))
        rect = False
    else:
        room_lookalikes = int(rng.integers(1, 5)) if rng.random() < 0.25 else 0
        rect = False
    wall_z = float(rng.uniform(0.15, 1.5))
    count = None
    if kind == "normal":
        count = _count_out_fn(cam, layout)
    ring = _square_ring(layout)
    for _ in range(12):
        path = draw_path(
            rng,
            duration_s=frames / fps,
            screen_m=screen_m,
            dist_m=dist,
            dist_range_m=dist_range,
            focal_px=cam.fx,
            exposure_s=exposure,
            max_blur_px=max_blur,
            count_out=count,
        )
        # the user starts aiming at the screen with the whole layout in the picture
        Cs, Rs = path.poses(np.array([0.0, path.t[1]]))
        if all(project(cam, C, R, ring)[1].all() for C, R in zip(Cs, Rs, strict=True)):
            break
        dist = min(dist * 1.15, dist_range[1])
        dist_range = (min(dist_range[0] * 1.1, dist), dist_range[1])
    return HandheldVideo(
        seed, kind, frames, cam, imaging, path, monitor, layout, wall_z, room_lookalikes, rect,
        max_blur, dist,
    )  # fmt: skip


def _square_ring(layout: LandmarkLayout, n: int = 6) -> FloatArray:
    """(4, 4n, 3) points on the edges of each landmark's white square (m, z = 0)."""
    h = layout.square_side_mm / 2000
    e = np.linspace(-h, h, n)
    ring = np.concatenate(
        [
            np.stack([e, np.full(n, -h)], 1),
            np.stack([e, np.full(n, h)], 1),
            np.stack([np.full(n, -h), e], 1),
            np.stack([np.full(n, h), e], 1),
        ]
    )
    c = layout.landmark_centers_mm() / 1000
    pts = c[:, None, :] + ring[None]
    return np.concatenate([pts, np.zeros((*pts.shape[:2], 1))], axis=2)


def project(
    cam: HandCamera, C: FloatArray, R: FloatArray, X: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """World points X (..., 3) -> distorted pixels (..., 2) and whether each is in the
    picture (in front, within the radius the image covers, inside the image)."""
    return _camera_to_pixels(cam, (X - C) @ R.T)


def _project_many(
    cam: HandCamera, C: FloatArray, R: FloatArray, X: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """:func:`project` with one pose per point: C (m, 3) or (m, 1, 3), R (m, 3, 3) or
    (m, 1, 3, 3), X (m, 3) or (m, k, 3)."""
    return _camera_to_pixels(cam, np.einsum("...ij,...j->...i", R, X - C))


def _camera_to_pixels(cam: HandCamera, Xc: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Camera-frame points Xc (..., 3) -> distorted pixels and whether each is in the
    picture (the second half of :func:`project`)."""
    z = Xc[..., 2]
    front = z > 1e-9
    xy = Xc[..., :2] / np.where(front, z, 1.0)[..., None]
    uv = cam.normalized_to_pixel(xy)
    r = np.linalg.norm(xy, axis=-1)
    inside = (
        front
        & (r <= _max_radius(cam))
        & (uv[..., 0] >= -0.5)
        & (uv[..., 0] <= cam.width - 0.5)
        & (uv[..., 1] >= -0.5)
        & (uv[..., 1] <= cam.height - 0.5)
    )
    return uv, inside


_RMAX: dict[HandCamera, float] = {}


def _max_radius(cam: HandCamera) -> float:
    if cam not in _RMAX:
        _RMAX[cam] = cam.max_normalized_radius()
    return _RMAX[cam]


def _count_out_fn(cam: HandCamera, layout: LandmarkLayout):  # type: ignore[no-untyped-def]
    ring = _square_ring(layout)

    def count(aim: FloatArray, C: FloatArray, roll: float) -> int:
        R = look_at_many(C[None], aim[None], np.array([roll]))[0]
        _, inside = project(cam, C, R, ring)
        return int(4 - inside.all(axis=1).sum())

    return count


# --------------------------------------------------------------------------- rendering


def _undistort_grid(cam: HandCamera, u: FloatArray, v: FloatArray) -> F32:
    """Undistorted normalized coordinates (H, W, 2) float32 of the pixels (u, v), by
    OpenCV's iterative undistortion (the same model as HandCamera; to ~1e-9)."""
    pts = np.stack([u.ravel(), v.ravel()], -1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    xy = cv2.undistortPoints(pts, cam.matrix(), cam.distortion(), R=None, P=None, criteria=crit)
    out: F32 = xy.reshape(*u.shape, 2).astype(np.float32)
    return out


def _pyramid(tex: NDArray[Any], min_side: int = 32) -> list[NDArray[Any]]:
    levels = [tex]
    while min(levels[-1].shape[:2]) > 2 * min_side:
        levels.append(np.asarray(cv2.pyrDown(levels[-1]), tex.dtype))
    return levels


def _plane_map(
    rays: F32,
    mats: FloatArray,
    edges: NDArray[np.int_],
    roi: tuple[int, int, int, int],
    border: FloatArray,
    Rs: FloatArray,
) -> F32:
    """The remap map (h, w, 2) float32 of a plane over ``roi`` = (r0, r1, c0, c1):
    ``rays`` (H, W, 2) through the band matrices ``mats`` (bands, 3, 3) (band b covers
    rows edges[b]:edges[b+1]). Rays that meet the plane behind the camera (checked on
    the picture's ``border`` rays (n, 2) with the bands' rotations ``Rs``) map far off
    the texture."""
    r0, r1, c0, c1 = roi
    out = np.empty((r1 - r0, c1 - c0, 2), np.float32)
    wz = border @ Rs[:, :2, 2].T + Rs[:, 2, 2]  # (n, bands): the ray's depth direction
    safe = bool(np.all(wz > 1e-3))
    for b in range(len(mats)):
        a, e = max(edges[b], r0), min(edges[b + 1], r1)
        if e <= a:
            continue
        part = rays[a:e, c0:c1]
        if safe:
            out[a - r0 : e - r0] = cv2.perspectiveTransform(
                part.reshape(-1, 1, 2), mats[b]
            ).reshape(e - a, c1 - c0, 2)
        else:
            M = mats[b]
            x, y = part[..., 0].astype(np.float64), part[..., 1].astype(np.float64)
            ww = M[2, 0] * x + M[2, 1] * y + M[2, 2]
            front = ww > 1e-9
            inv = 1.0 / np.where(front, ww, 1.0)
            out[a - r0 : e - r0, :, 0] = np.where(
                front, (M[0, 0] * x + M[0, 1] * y + M[0, 2]) * inv, -1e5
            )
            out[a - r0 : e - r0, :, 1] = np.where(
                front, (M[1, 0] * x + M[1, 1] * y + M[1, 2]) * inv, -1e5
            )
    return out


def _plane_matrix(C: FloatArray, R: FloatArray, z0: float) -> FloatArray:
    """(N, 3, 3): camera ray (x, y, 1) -> homogeneous world (X, Y, 1) on the plane z = z0;
    the third coordinate is positive exactly when the point is in front of the camera."""
    dz = (z0 - C[:, 2])[:, None]
    rx = dz * R[:, :, 0] + C[:, 0:1] * R[:, :, 2]
    ry = dz * R[:, :, 1] + C[:, 1:2] * R[:, :, 2]
    out: FloatArray = np.stack([rx, ry, R[:, :, 2]], axis=1)
    return out


def _texture_matrix(origin: tuple[float, float], px_per_m: float, level: int) -> FloatArray:
    """World (X, Y, 1) -> texel coordinates at pyramid ``level`` (centre of texel 0 = 0)."""
    # level 0: u0 = (X - x0) ppm - 0.5; cv2.pyrDown keeps the blurred texels 0, 2, 4, ...
    # so texel i of level L sits at u0 = 2^L i
    s = px_per_m / 2**level
    return np.array(
        [
            [s, 0.0, (-origin[0] * px_per_m - 0.5) / 2**level],
            [0.0, s, (-origin[1] * px_per_m - 0.5) / 2**level],
            [0.0, 0.0, 1.0],
        ]
    )


@dataclass
class _Plane:
    """A textured plane at z: pyramid (uint16, BGR or premultiplied BGRA), origin (m) of
    texel (-0.5, -0.5) and texels per metre at level 0."""

    z: float
    levels: list[NDArray[np.uint16]]
    origin: tuple[float, float]
    px_per_m: float
    border: int
    dynamic: Any = None
    cache: dict[int, NDArray[np.uint16]] = field(default_factory=dict)


class HandheldRenderer:
    """Renders the frames of a :class:`HandheldVideo` (BGR uint8) and their truth.

    Textures and their pyramids, the undistorted ray grids of four sub-pixel sample
    positions, the vignetting map and the gamma table are made once per video; each
    frame costs 4-24 sub-frame renders (motion blur, rolling shutter by 16-row bands,
    sub-pixel jitter) of two ``cv2.remap`` calls, then the camera's processing.
    """

    def __init__(self, video: HandheldVideo) -> None:
        self.video = video
        cam = video.camera
        self.cam = cam
        rng = np.random.default_rng([video.seed, 77])
        w, h = cam.width, cam.height
        offs = ((-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25))
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        self.rays = [_undistort_grid(cam, u + ox, v + oy) for ox, oy in offs]
        # the wall's half-resolution grid: half pixel (i, j) covers full pixels 2i, 2i+1
        self.half_size = ((h + 1) // 2, (w + 1) // 2)
        hu, hv = np.meshgrid(
            2 * np.arange(self.half_size[1], dtype=np.float64) + 0.5,
            2 * np.arange(self.half_size[0], dtype=np.float64) + 0.5,
        )
        self.half_rays = [_undistort_grid(cam, hu + 2 * ox, hv + 2 * oy) for ox, oy in offs]
        bu = np.concatenate([np.arange(w), np.full(h, w - 1), np.arange(w), np.zeros(h)])
        bv = np.concatenate([np.zeros(w), np.arange(h), np.full(w, h - 1), np.arange(h)])
        self.border_dz = cam.pixel_to_normalized(np.stack([bu, bv], -1) + 0.0)
        # sample times: how far each pose lookup and the textures' resolution must reach
        t = np.arange(video.frames) / video.imaging.fps
        Cs, Rs = video.path.poses(t)
        self._poses_t = t
        self.monitor_plane: _Plane | None = None
        if video.monitor is not None:
            self.monitor_plane = self._monitor_plane(rng, Cs)
        self.wall = self._wall_plane(rng, Cs, Rs)
        im = video.imaging
        r2 = ((u - cam.cx) ** 2 + (v - cam.cy) ** 2) / (w * w / 4 + h * h / 4)
        vig = (1.0 - im.vignette * r2).astype(np.float32)
        self.shade = np.stack([vig * np.float32(b) for b in im.white_balance], -1)
        x = np.linspace(0.0, 1.0, 4097)
        self.gamma_lut = np.round(255 * x ** (1 / im.gamma)).astype(np.uint8)
        self.gain: float | None = None
        self._last = -1
        # sensor noise: crops of one bank of N(0, 1) at random offsets, per frame
        self.noise = np.random.default_rng([video.seed, 78]).standard_normal(
            (h + 64, w + 64, 3), dtype=np.float32
        )
        self.ring = _square_ring(video.layout)
        self.centres = np.column_stack([video.layout.landmark_centers_mm() / 1000, np.zeros(4)])
        self.blur = self._blur_all()
        self._truth: list[dict[str, Any]] | None = None

    # --------------------------------------------------------------- textures
    def _light(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        im = self.video.imaging
        W, H = self.video.layout.screen_width_mm / 1000, self.video.layout.screen_height_mm / 1000
        g = 1 + im.light_gradient[0] * (X - W / 2) + im.light_gradient[1] * (Y - H / 2)
        out: FloatArray = im.room_light * np.clip(g, 0.4, 1.6)
        return out

    def _monitor_plane(self, rng: np.random.Generator, Cs: FloatArray) -> _Plane:
        m = self.video.monitor
        assert m is not None
        W, H = m.screen_m
        bl, bt, br, bb = m.bezel_m
        lay = m.layout
        lc = lay.landmark_centers_mm() / 1000
        hs = lay.square_side_mm / 2000
        x0 = min(-bl, float(lc[:, 0].min()) - hs) - 0.005
        y0 = min(-bt, float(lc[:, 1].min()) - hs) - 0.005
        x1 = max(W + br, float(lc[:, 0].max()) + hs) + 0.005
        y1 = max(H + bb, float(lc[:, 1].max()) + hs) + 0.005
        depth = float(np.min(Cs[:, 2] * -1.0))
        ppm = min(1.3 * self.cam.fx / max(depth, 0.05), 2048 / (x1 - x0))
        nx, ny = math.ceil((x1 - x0) * ppm), math.ceil((y1 - y0) * ppm)
        X = np.asarray(x0 + (np.arange(nx) + 0.5) / ppm, np.float64)
        Y = np.asarray(y0 + (np.arange(ny) + 0.5) / ppm, np.float64)
        light = self._light(X[None, :], Y[:, None]).astype(np.float32)[..., None]
        rgba = np.zeros((ny, nx, 4), np.float32)
        # bezel
        bx0, by0 = round((-bl - x0) * ppm), round((-bt - y0) * ppm)
        bx1, by1 = round((W + br - x0) * ppm), round((H + bb - y0) * ppm)
        rgba[by0:by1, bx0:bx1, :3] = np.asarray(m.bezel_refl, np.float32)
        rgba[by0:by1, bx0:bx1, 3] = 1.0
        # landmark cards (reflective), then lit with the bezel
        card = np.zeros((ny, nx, 3), np.float32)
        cmask = np.zeros((ny, nx), np.float32)
        for cx, cy in lc:
            u, v = (cx - x0) * ppm - 0.5, (cy - y0) * ppm - 0.5
            d_px, s_px = lay.circle_diameter_mm / 1000 * ppm, lay.square_side_mm / 1000 * ppm
            lookalike(card, (u, v), d_px, s_px, white=m.card_white, black=m.disc_black)
            half = s_px / 2
            p0 = (round((u - half) * 16), round((v - half) * 16))
            p1 = (round((u + half) * 16), round((v + half) * 16))
            cv2.rectangle(cmask, p0, p1, 1.0, -1, cv2.LINE_AA, 4)
        a = cmask[..., None]
        rgba[..., :3] = rgba[..., :3] * (1 - a) + card  # card is drawn premultiplied
        rgba[..., 3] = np.maximum(rgba[..., 3], cmask)
        rgba[..., :3] *= light
        # the screen (emissive) inside the bezel; cards may overlap its corners? no:
        # they sit outside the lit area
        sx0, sy0 = round((0 - x0) * ppm), round((0 - y0) * ppm)
        sx1, sy1 = round((W - x0) * ppm), round((H - y0) * ppm)
        d_tex = lay.circle_diameter_mm / 1000 * ppm
        content = screen_content(
            rng,
            sx1 - sx0,
            sy1 - sy0,
            kind=m.content_kind,
            lookalike_texels=(d_tex, lay.square_side_mm / 1000 * ppm),
            lookalikes=m.screen_lookalikes,
        )
        scr = content.base * np.float32(m.screen_white)
        rgba[sy0:sy1, sx0:sx1, :3] = scr
        rgba[sy0:sy1, sx0:sx1, 3] = 1.0
        # cards drawn over the screen's edge where they overhang it
        over = cmask[sy0:sy1, sx0:sx1, None]
        rgba[sy0:sy1, sx0:sx1, :3] = rgba[sy0:sy1, sx0:sx1, :3] * (1 - over) + (
            card[sy0:sy1, sx0:sx1] * light[sy0:sy1, sx0:sx1]
        )
        tex = np.clip(rgba * np.array([_U16, _U16, _U16, 65535.0], np.float32), 0, 65535)
        plane = _Plane(0.0, _pyramid(tex.astype(np.uint16)), (x0, y0), ppm, cv2.BORDER_CONSTANT)
        if content.video_box is not None:
            plane.dynamic = (content, (sx0, sy0), m.screen_white)
        return plane

    def _wall_plane(self, rng: np.random.Generator, Cs: FloatArray, Rs: FloatArray) -> _Plane:
        v = self.video
        cam = self.cam
        zw = v.wall_z
        corners = np.array(
            [
                [-0.5, -0.5],
                [cam.width - 0.5, -0.5],
                [cam.width - 0.5, cam.height - 0.5],
                [-0.5, cam.height - 0.5],
            ]
        )
        xy = cam.pixel_to_normalized(corners)
        rays = np.column_stack([xy, np.ones(4)])
        step = max(1, len(Cs) // 60)
        pts = []
        for C, R in zip(Cs[::step], Rs[::step], strict=True):
            d = rays @ R  # world directions (R^T r)
            s = (zw - C[2]) / np.maximum(d[:, 2], 0.05)
            pts.append(C[:2] + s[:, None] * d[:, :2])
        p = np.concatenate(pts)
        x0, y0 = p.min(axis=0) - 0.3
        x1, y1 = p.max(axis=0) + 0.3
        depth = float(np.min(zw - Cs[:, 2]))
        ppm = min(1.0 * cam.fx / depth, 1536 / (x1 - x0), 1536 / (y1 - y0))
        nx, ny = math.ceil((x1 - x0) * ppm), math.ceil((y1 - y0) * ppm)
        lay = v.layout
        look = (lay.circle_diameter_mm / 1000, lay.square_side_mm / 1000)
        rect = None
        if v.lookalike_rect:
            c = lay.landmark_centers_mm() / 1000
            k = float(rng.uniform(0.6, 1.4))
            asp = float(rng.uniform(0.75, 1.33))
            mid = c.mean(axis=0) + rng.normal(0, 0.05, 2)
            hw = (c[1, 0] - c[0, 0]) / 2 * k * math.sqrt(asp)
            hh = (c[3, 1] - c[0, 1]) / 2 * k / math.sqrt(asp)
            rect = (
                (mid[0] - hw - x0) * ppm,
                (mid[1] - hh - y0) * ppm,
                (mid[0] + hw - x0) * ppm,
                (mid[1] + hh - y0) * ppm,
            )
        refl = room_texture(
            rng, nx, ny, ppm, lookalike_m=look, lookalikes=v.room_lookalikes, lookalike_rect=rect
        )
        X = x0 + (np.arange(nx) + 0.5) / ppm
        Y = y0 + (np.arange(ny) + 0.5) / ppm
        light = self._light(X[None, :], Y[:, None]).astype(np.float32)[..., None]
        tex = np.clip(refl * light * np.float32(_U8) + 0.5, 0, 255).astype(np.uint8)
        return _Plane(zw, _pyramid(tex), (x0, y0), ppm, cv2.BORDER_REFLECT)

    # --------------------------------------------------------------- frames
    def _level(self, plane: _Plane, C: FloatArray, R: FloatArray) -> int:
        """Pyramid level whose texels are about one image pixel at the picture's centre."""
        ray = np.array([0.0, 0.0, 1.0])
        d = R.T @ ray
        s = (plane.z - C[2]) / max(d[2], 1e-3)
        depth = s  # distance along the axis
        scale = plane.px_per_m * depth / self.cam.fx  # texels per image pixel
        return int(np.clip(math.floor(math.log2(max(scale, 1.0))), 0, len(plane.levels) - 1))

    def _texture(self, plane: _Plane, level: int, t: float) -> NDArray[np.uint16]:
        if plane.dynamic is None:
            return plane.levels[level]
        content, (sx0, sy0), white = plane.dynamic
        tex = plane.levels[level].copy()
        frame = video_frame(content, t)
        assert frame is not None and content.video_box is not None
        bx0, by0, bx1, by1 = content.video_box
        s = 2.0**level
        X0, Y0 = round((sx0 + bx0) / s), round((sy0 + by0) / s)
        X1, Y1 = round((sx0 + bx1) / s), round((sy0 + by1) / s)
        if X1 > X0 and Y1 > Y0:
            small = cv2.resize(frame, (X1 - X0, Y1 - Y0), interpolation=cv2.INTER_AREA)
            tex[Y0:Y1, X0:X1, :3] = np.clip(small * (white * _U16), 0, 65535).astype(np.uint16)
        return tex

    def _blur_all(self) -> FloatArray:
        """(frames,) largest image motion (px) of the landmark centres over each frame's
        exposure."""
        v = self.video
        te = v.imaging.exposure_s
        t = np.arange(v.frames) / v.imaging.fps
        C, R = v.path.poses(np.concatenate([t - te / 2, t + te / 2]))
        X = np.tile(self.centres, (len(C), 1))
        uv, _ = _project_many(self.cam, np.repeat(C, 4, axis=0), np.repeat(R, 4, axis=0), X)
        a, b = uv.reshape(2, v.frames, 4, 2)
        out: FloatArray = np.max(np.linalg.norm(a - b, axis=2), axis=1)
        return out

    def _monitor_roi(self, Cs: FloatArray, Rs: FloatArray) -> tuple[int, int, int, int] | None:
        """Rows and columns (r0, r1, c0, c1) of the picture the monitor can cover in a
        sub-frame (poses of its bands ``Cs`` (b, 3), ``Rs`` (b, 3, 3)), None if none."""
        p = self.monitor_plane
        assert p is not None
        cam = self.cam
        h, w = p.levels[0].shape[:2]
        x0, y0 = p.origin
        x1, y1 = x0 + w / p.px_per_m, y0 + h / p.px_per_m
        e = np.linspace(0, 1, 6)
        pts = np.concatenate(
            [
                np.stack([x0 + (x1 - x0) * e, np.full(6, y0)], 1),
                np.stack([x0 + (x1 - x0) * e, np.full(6, y1)], 1),
                np.stack([np.full(6, x0), y0 + (y1 - y0) * e], 1),
                np.stack([np.full(6, x1), y0 + (y1 - y0) * e], 1),
            ]
        )
        X = np.column_stack([pts, np.zeros(len(pts))])
        lo = np.array([np.inf, np.inf])
        hi = -lo
        for C, R in zip(Cs[[0, -1]], Rs[[0, -1]], strict=True):
            Xc = (X - C) @ R.T
            if np.any(Xc[:, 2] < 0.05):
                return (0, cam.height, 0, cam.width)
            xy = Xc[:, :2] / Xc[:, 2:3]
            if np.any(np.linalg.norm(xy, axis=1) > _max_radius(cam)):
                return (0, cam.height, 0, cam.width)
            uv = cam.normalized_to_pixel(xy)
            lo, hi = np.minimum(lo, uv.min(axis=0)), np.maximum(hi, uv.max(axis=0))
        c0, r0 = np.floor(lo - 3).astype(int)
        c1, r1 = np.ceil(hi + 3).astype(int)
        c0, r0 = max(c0, 0), max(r0, 0)
        c1, r1 = min(c1, cam.width), min(r1, cam.height)
        if c1 <= c0 or r1 <= r0:
            return None
        return (int(r0), int(r1), int(c0), int(c1))

    def render(self, index: int) -> NDArray[np.uint8]:
        """Frame ``index`` (BGR uint8). Frames must be asked for in order (auto-exposure
        follows them); asking for an earlier frame restarts the exposure from frame 0."""
        v = self.video
        im = v.imaging
        cam = self.cam
        w, h = cam.width, cam.height
        if index <= self._last:
            self.gain = None
            for i in range(index):
                self.render(i)
        t = index / im.fps
        blur = float(self.blur[index]) if index < len(self.blur) else 0.0
        K = int(np.clip(math.ceil(blur / 1.5) + 1, 2, 24))
        bands = max(1, h // 16) if im.readout_s > 0 else 1
        rows = (np.arange(bands) + 0.5) * h / bands
        rc = (h - 1) / 2
        sub = ((np.arange(K) + 0.5) / K - 0.5) * im.exposure_s
        times = t + sub[:, None] + ((rows - rc) / h * im.readout_s)[None, :]  # (K, bands)
        Cs, Rs = v.path.poses(times.ravel())
        C0, R0 = v.path.poses(np.array([t]))
        planes = [p for p in (self.wall, self.monitor_plane) if p is not None]
        levels = [self._level(p, C0[0], R0[0]) for p in planes]
        levels[0] = min(levels[0] + 1, len(self.wall.levels) - 1)  # the wall a little soft
        texs = [self._texture(p, lv, t) for p, lv in zip(planes, levels, strict=True)]
        mats = []
        for p, lv in zip(planes, levels, strict=True):
            M = _texture_matrix(p.origin, p.px_per_m, lv) @ _plane_matrix(Cs, Rs, p.z)
            mats.append(M.reshape(K, bands, 3, 3))
        edges = np.linspace(0, h, bands + 1).round().astype(int)
        self.half_edges = (edges + 1) // 2
        # The wall is rendered at half resolution (it is background) and the sub-frames
        # are summed apart: wall, monitor (premultiplied) and its coverage; the wall
        # under a moving monitor edge is then the exposure's mean wall.
        hw, ww = self.half_size
        wall_acc = np.zeros((hw, ww, 3), np.float32)
        mon_acc = np.zeros((h, w, 4), np.float32)
        Rk = Rs.reshape(K, bands, 3, 3)
        Ck = Cs.reshape(K, bands, 3)
        for k in range(K):
            j = (k % 2) * 3 if K == 2 else k % 4
            mw = _plane_map(self.half_rays[j], mats[0][k], self.half_edges, (0, hw, 0, ww),
                            self.border_dz, Rk[k])  # fmt: skip
            cv2.accumulate(
                cv2.remap(texs[0], mw, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT),  # type: ignore[call-overload]
                wall_acc,
            )
            roi = self._monitor_roi(Ck[k], Rk[k]) if len(planes) == 2 else None
            if roi is not None:
                r0, r1, c0, c1 = roi
                mm = _plane_map(self.rays[j], mats[1][k], edges, roi, self.border_dz, Rk[k])
                mon = cv2.remap(texs[1], mm, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)  # type: ignore[call-overload]
                cv2.accumulate(mon, mon_acc[r0:r1, c0:c1])
        wall = cv2.resize(wall_acc, (w, h), interpolation=cv2.INTER_LINEAR)
        # wall x (1 - coverage) + premultiplied monitor, both as exposure means
        weight: F32 = np.asarray(cv2.merge([cv2.extractChannel(mon_acc, 3)] * 3), np.float32)
        weight *= np.float32(-1 / (65535 * K * K * _U8))
        weight += np.float32(1 / (K * _U8))
        img: F32 = np.asarray(cv2.multiply(wall, weight), np.float32)
        cv2.scaleAdd(cv2.cvtColor(mon_acc, cv2.COLOR_BGRA2BGR), 1 / (K * _U16), img, dst=img)
        if im.defocus_px > 0.3:
            img = np.asarray(cv2.GaussianBlur(img, (0, 0), im.defocus_px), np.float32)
        img *= self.shade
        mean = float(img[::4, ::4].mean())
        want = im.ae_target / max(mean, 1e-4)
        if self.gain is None:
            self.gain = want
        else:
            self.gain *= (want / self.gain) ** im.ae_rate
        self.gain = float(np.clip(self.gain, 0.25, 16.0))
        g = self.gain
        img *= np.float32(g)
        rng = np.random.default_rng([v.seed, index, 5])
        dy, dx = (int(q) for q in rng.integers(0, 64, 2))
        noise = self.noise[dy : dy + h, dx : dx + w]
        if rng.random() < 0.5:
            noise = -noise
        np.maximum(img, 0, out=img)
        sigma = cv2.sqrt(img * np.float32(im.shot * g) + np.float32((im.read * g) ** 2))
        img += noise * sigma
        np.clip(img, 0.0, 1.0, out=img)
        out8 = self.gamma_lut[(img * np.float32(4096)).astype(np.uint16)]
        ok, buf = cv2.imencode(".jpg", out8, [cv2.IMWRITE_JPEG_QUALITY, im.jpeg_quality])
        assert ok
        frame = np.asarray(cv2.imdecode(buf, cv2.IMREAD_COLOR), np.uint8)
        self._last = index
        return frame

    # --------------------------------------------------------------- truth
    def _truths(self) -> list[dict[str, Any]]:
        """Every frame's truth (see :meth:`truth`), computed for the whole video at once."""
        v = self.video
        cam = self.cam
        im = v.imaging
        n = v.frames
        t = np.arange(n) / im.fps
        C, R = v.path.poses(t)
        centre_px = np.array([(cam.width - 1) / 2, (cam.height - 1) / 2])
        xy = cam.pixel_to_normalized(centre_px)
        d = np.einsum("nji,j->ni", R, np.array([xy[0], xy[1], 1.0]))  # R^T ray
        W, H = v.layout.screen_width_mm / 1000, v.layout.screen_height_mm / 1000
        hit = (d[:, 2] > 1e-9) & (v.monitor is not None)
        s = -C[:, 2] / np.where(hit, d[:, 2], 1.0)
        P = C + s[:, None] * d
        px = P[:, :2] / (np.array([W, H]) / np.array(SCREEN_PX)) - 0.5  # screen pixel centres
        nxy = px / (np.array(SCREEN_PX) - 1)
        on = hit & (P[:, 0] >= 0) & (P[:, 0] <= W) & (P[:, 1] >= 0) & (P[:, 1] <= H)
        # each landmark at its own row's time under the rolling shutter (3 fixed-point steps)
        rc = (cam.height - 1) / 2
        tk = np.repeat(t, 4)
        X = np.tile(self.centres, (n, 1))
        for _ in range(3):
            Ck, Rk = v.path.poses(tk)
            uv, ins = _project_many(cam, Ck, Rk, X)
            tk = np.repeat(t, 4) + (uv[:, 1] - rc) / cam.height * im.readout_s
        ring = np.repeat(self.ring[None], n, axis=0).reshape(n * 4, -1, 3)
        _, ring_in = _project_many(cam, Ck[:, None], Rk[:, None], ring)
        front = np.einsum("mij,mj->mi", Rk, X - Ck)[:, 2] > 0
        present = v.monitor is not None
        uv, ins = uv.reshape(n, 4, 2), ins.reshape(n, 4)
        visible = ring_in.all(axis=1).reshape(n, 4) & present
        front = front.reshape(n, 4) & present
        aim, camc, roll = v.path.state(t)
        view = np.degrees(np.arccos(np.minimum(1.0, np.abs(R[:, 2, 2]))))
        dist = np.linalg.norm(aim - camc, axis=1)
        starts = np.array([st for st, _ in v.path.segments])
        seg = np.searchsorted(starts, t + 1e-9, side="right") - 1
        out = []
        for i in range(n):
            out.append(
                {
                    "index": i,
                    "t": float(t[i]),
                    "screen_xy": [float(nxy[i, 0]), float(nxy[i, 1])] if hit[i] else None,
                    "screen_px": [float(px[i, 0]), float(px[i, 1])] if hit[i] else None,
                    "on_screen": bool(on[i]),
                    "landmarks_uv": [
                        [float(uv[i, k, 0]), float(uv[i, k, 1])] if front[i, k] else None
                        for k in range(4)
                    ],
                    "visible": [bool(b) for b in visible[i]],
                    "centre_inside": [bool(b and present) for b in ins[i]],
                    "blur_px": round(float(self.blur[i]), 3),
                    "view_angle_deg": round(float(view[i]), 3),
                    "roll_deg": round(float(roll[i]), 3),
                    "distance_m": round(float(dist[i]), 4),
                    "segment": v.path.segments[seg[i]][1] if seg[i] >= 0 else "dwell",
                }
            )
        return out

    def truth(self, index: int) -> dict[str, Any]:
        """Frame ``index``'s truth (see the module docstring), JSON-ready."""
        if self._truth is None:
            self._truth = self._truths()
        return self._truth[index]


def write_video(
    seed: int, outdir: Path, *, frames: int = 300, force: bool = False
) -> dict[str, Any]:
    """Render video ``seed`` into ``outdir`` atomically, as the fixtures of
    :mod:`omnidev.sim.monitor` are laid out (``omnidev mouse-eval`` reads it):
    ``mouse.avi`` (MJPG, quality 95, of the frames the webcam delivered),
    ``truth.json`` (the drawn parameters under ``video`` and the per-frame truth) and
    ``landmarks.json`` (the layout). Returns what truth.json holds."""
    import json

    from omnidev.atomic import atomic_dir, check_output_dir
    from omnidev.errors import OutputError

    outdir = Path(outdir)
    check_output_dir(outdir, force=force)
    video = draw_video(seed, frames=frames)
    r = HandheldRenderer(video)
    cam = video.camera
    with atomic_dir(outdir, force=force) as tmp:
        size = (cam.width, cam.height)
        vw = cv2.VideoWriter(
            str(tmp / "mouse.avi"), cv2.VideoWriter.fourcc(*"MJPG"), video.imaging.fps, size
        )
        if not vw.isOpened():
            raise OutputError(f"cannot write MJPG video in {tmp}")
        vw.set(cv2.VIDEOWRITER_PROP_QUALITY, 95)
        per_frame = []
        for i in range(frames):
            vw.write(r.render(i))
            per_frame.append(r.truth(i))
        vw.release()
        doc = {
            "video": video.describe(),
            "camera": {"width": cam.width, "height": cam.height},
            "per_frame": per_frame,
            "regenerate": f"omnidev eval mouse --scene-seed {seed} --opt frames={frames} "
            "--write DIR",
        }
        (tmp / "truth.json").write_text(json.dumps(doc, indent=1) + "\n")
        (tmp / "landmarks.json").write_text(json.dumps(video.layout_dict(), indent=2) + "\n")
    return doc
