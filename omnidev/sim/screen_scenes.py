"""Randomized scenes of a fixed camera watching a screen, each drawn from a seed, with exact truth.

The world the screen-calibration, laser and camera-mouse evaluations run in
(issue 12): every scene draws its camera (resolution 320x240 .. 1920x1080,
field of view, principal point, radial distortion k1 -0.35 .. +0.2 with k2),
its pose (yaw and pitch up to 35 degrees, roll, distance, aim), its screen
(monitor or projector; resolution, size, aspect, keystone, hot spot, viewing
angle fall-off, glare, display gamma 1.8-2.4, black level, white balance), its
room (strongly textured walls, doors, windows that shine and change, picture
frames, posters, whiteboards and screen-like rectangles beside the screen,
light that is uneven and changes, screen light spilling on the wall, mains
flicker, an occluder in front of the screen) and its camera electronics
(exposure, auto-exposure strength and lag, exposure drift, colour cast,
defocus, veiling flare, lateral chromatic aberration, blooming, Bayer
demosaicing, shot and read noise, sharpening, camera gamma 1.8-2.4, rolling
shutter, and per-sequence compression: none, JPEG/MJPEG, MPEG-4 or H.264).

API
---
``scene = draw_scene(seed, ranges=SceneRanges())``
    A :class:`ScreenScene`: every parameter drawn from ``seed`` (frozen,
    ``scene.to_dict()`` for JSON, ``scene.classes()`` for reporting).
    :class:`SceneRanges` narrows or widens the ranges (e.g. no occluder,
    only 1280x720, only H.264).
``scene.image_to_screen(uv)`` / ``scene.screen_to_image(xy)``
    The exact truth: image px (N, 2) <-> screen px (N, 2) on the screen plane
    (the plane continues beyond the screen; NaN where the ray misses it,
    behind the camera, or beyond the lens's monotonic range). The camera is
    fixed, so this holds for every frame; ``scene.visible(xy)`` also says
    whether a screen point is in the picture and not behind the occluder.
``renderer = SceneRenderer(scene)``
    Precomputes every sub-pixel ray's hit on the screen plane (cached per
    scene). ``renderer.render(content, t=..., exposure=..., extra_light=...)``
    renders one frame before compression: H x W x 3 BGR uint8.
``capture_stills(scene, contents, ...)``
    Calibration captures: each displayed content (BGR or grey uint8, screen
    px) held for a few frames of one compressed stream (auto-exposure settles
    as it would), the last frame of each returned.
``render_sequence(scene, frames, fps=30)``
    A video: :class:`FrameInput` items (content, time ``t``, extra light) ->
    :class:`Capture` items (compressed image, t, exposure), with the
    auto-exposure's lag and drift and the scene's compression.

Extra light on the screen plane (a laser spot) is a callable
``extra_light(xy_screen_px: (N, 2) float64) -> (N, 3) float64`` (B, G, R),
linear radiance in units of the display's white (1.0 = what the display shows
for 255 at the screen centre; may be >> 1), evaluated at each camera
sub-pixel ray's hit point, so a spot is analytic; ``extra_light_t(xy, t)``
also receives each sample's time in seconds (rolling shutter: the row's start
of exposure; ``motion_samples`` > 1 spreads samples over the exposure, for
motion blur). ``extra_light_bbox = (x0, y0, x1, y1)`` screen px bounds where
the light is non-zero: only the sub-pixels that can see it are evaluated.

Light model (all linear, display white = 1): a screen pixel of value ``s``
shows ``black + (1 - black) (s / 255)^gamma_display`` times the display's
white balance and spatial gain (hot spot, vignetting, viewing angle); the
wall reflects the room light (uneven, slowly changing, flickering with the
rows' times) and the screen's spill light, windows and a second monitor
emit. The camera multiplies by its exposure and colour gains, clips each
channel on its own at 1.0 (a pure-red spot clips red while green and blue
stay below; blooming spills the excess), adds noise, demosaics, applies its
gamma and quantizes to 8 bits.

Frames and units (as :mod:`omnidev.sim.screen`): world metres, the screen
plane z = 0, x right, y down, z into the wall; ``X_cam = R X_world + t``;
screen px (x, y) and image px (u, v) with the centre of the top-left pixel
at (0, 0); the lens is OpenCV's radial model (k1, k2) on normalized
coordinates. Screen px -> plane: ``(X, Y, 1) ~ Hs (x + 0.5, y + 0.5, 1)``
(a scaling for monitors, a mild keystone homography for projectors).

Example:
    >>> scene = draw_scene(7)
    >>> uv = scene.screen_to_image(np.array([[960.0, 540.0]]))
    >>> bool(np.allclose(scene.image_to_screen(uv), [[960.0, 540.0]], atol=1e-6))
    True
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.sim.codec import Compression, compress_frames
from omnidev.sim.handcam import look_at

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]
ExtraLight = Callable[[FloatArray], FloatArray]
TimedExtraLight = Callable[[FloatArray, FloatArray], FloatArray]

RESOLUTIONS: tuple[tuple[int, int], ...] = (
    (320, 240),
    (352, 288),
    (424, 240),
    (640, 360),
    (640, 480),
    (800, 600),
    (960, 540),
    (1024, 768),
    (1280, 720),
    (1280, 960),
    (1600, 900),
    (1920, 1080),
)
SCREEN_RESOLUTIONS: tuple[tuple[int, int], ...] = (
    (1920, 1080),
    (1280, 720),
    (1366, 768),
    (1920, 1200),
    (1280, 1024),
    (1024, 768),
    (2560, 1440),
)
_OFF = np.float32(-1.0e5)  # sub-pixel screen coordinate of a ray that sees no plane


def _choice(rng: np.random.Generator, weights: dict[str, float]) -> str:
    keys = list(weights)
    p = np.array([weights[k] for k in keys], float)
    return str(keys[int(rng.choice(len(keys), p=p / p.sum()))])


@dataclass(frozen=True)
class SceneRanges:
    """The ranges scenes are drawn from (defaults: issue 12's world, and wider).

    Resolutions are drawn uniformly from ``resolutions``; the screen
    resolution from ``screen_resolutions`` (the first with probability
    ``first_screen_weight``, the others uniformly). Angles in degrees.
    ``fill``: the screen's extent over the image's, for uncropped scenes;
    ``crop_prob``: scenes with part of the screen out of the picture;
    ``occluder_prob``: scenes with something in front of the screen.
    ``codecs`` and ``screen_kinds``: weights. ``ae_prob``: scenes with
    auto-exposure on (else the exposure is locked, drift only).
    """

    resolutions: tuple[tuple[int, int], ...] = RESOLUTIONS
    screen_resolutions: tuple[tuple[int, int], ...] = SCREEN_RESOLUTIONS
    first_screen_weight: float = 0.6
    k1: tuple[float, float] = (-0.35, 0.2)
    hfov_deg: tuple[float, float] = (45.0, 90.0)
    yaw_deg: float = 35.0
    pitch_deg: float = 35.0
    roll_deg: float = 6.0
    fill: tuple[float, float] = (0.35, 0.95)
    crop_prob: float = 0.05
    occluder_prob: float = 0.08
    codecs: tuple[tuple[str, float], ...] = (
        ("none", 0.15),
        ("jpeg", 0.35),
        ("mpeg4", 0.2),
        ("h264", 0.3),
    )
    screen_kinds: tuple[tuple[str, float], ...] = (("monitor", 0.5), ("projector", 0.5))
    ae_prob: float = 0.6
    distractors: tuple[int, int] = (2, 8)


DEFAULT_RANGES = SceneRanges()


# ---------------------------------------------------------------- the lens


@dataclass(frozen=True)
class SceneCamera:
    """Pinhole + OpenCV radial distortion: size (px), fx, fy, cx, cy (px), k1, k2."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float
    k2: float

    def radius_limit(self) -> float:
        """The undistorted normalized radius where r (1 + k1 r^2 + k2 r^4) stops increasing
        (inf if it never does)."""
        a, b, c = 5.0 * self.k2, 3.0 * self.k1, 1.0  # in s = r^2
        roots = np.roots([a, b, c]) if abs(a) > 1e-15 else np.roots([b, c])
        s = [float(z.real) for z in np.atleast_1d(roots) if abs(z.imag) < 1e-12 and z.real > 0]
        return math.sqrt(min(s)) if s else math.inf

    def distort(self, r: FloatArray) -> FloatArray:
        """Distorted radius of undistorted normalized radius ``r``."""
        r2 = r * r
        out: FloatArray = r * (1.0 + self.k1 * r2 + self.k2 * r2 * r2)
        return out

    def undistort_radius(self, rd: FloatArray) -> FloatArray:
        """r with distort(r) = rd (a table then Newton; NaN beyond the monotonic range)."""
        lim = min(self.radius_limit(), 50.0)
        r_tab = np.linspace(0.0, lim, 20001)
        d_tab = self.distort(r_tab)
        r = np.interp(rd, d_tab, r_tab)
        for _ in range(4):
            r2 = r * r
            f = r * (1.0 + self.k1 * r2 + self.k2 * r2 * r2) - rd
            r = r - f / (1.0 + 3.0 * self.k1 * r2 + 5.0 * self.k2 * r2 * r2)
        return np.where(rd <= d_tab[-1] * (1 + 1e-12), r, np.nan)

    def pixels_to_normalized(self, uv: FloatArray) -> FloatArray:
        """Image px (..., 2) -> undistorted normalized (..., 2) (NaN beyond the lens's range)."""
        xd = (uv[..., 0] - self.cx) / self.fx
        yd = (uv[..., 1] - self.cy) / self.fy
        rd = np.hypot(xd, yd)
        r = self.undistort_radius(rd)
        scale = np.where(rd > 0, r / np.where(rd > 0, rd, 1.0), 1.0)
        return np.stack([xd * scale, yd * scale], -1)

    def normalized_to_pixels(self, xy: FloatArray) -> FloatArray:
        """Undistorted normalized (N, 2) -> image px (N, 2) (NaN beyond the lens's range)."""
        r = np.hypot(xy[:, 0], xy[:, 1])
        k = 1.0 + self.k1 * r * r + self.k2 * r**4
        uv = np.column_stack([self.fx * xy[:, 0] * k + self.cx, self.fy * xy[:, 1] * k + self.cy])
        uv[r > self.radius_limit()] = np.nan
        return uv


# ---------------------------------------------------------------- scene description


@dataclass(frozen=True)
class WallObject:
    """A rectangle on the wall plane (m): ``kind`` (door, window, picture, poster,
    monitor_off, monitor_on, whiteboard, shelf), ``x0, y0, x1, y1``, frame width
    ``frame_m``, colours (B, G, R reflectance 0..1) of frame and body, ``emission``
    (windows and a live monitor, units of display white), its own ``seed``."""

    kind: str
    x0: float
    y0: float
    x1: float
    y1: float
    frame_m: float
    frame_colour: tuple[float, float, float]
    body_colour: tuple[float, float, float]
    emission: float
    seed: int


@dataclass(frozen=True)
class ScreenScene:
    """One randomized scene (see the module docstring). Frozen; draw with :func:`draw_scene`.

    Geometry: ``camera``, ``R`` (3x3), ``t`` (3,) world -> camera, ``screen_px``
    (W, H), ``screen_m`` (nominal lit size, m), ``Hs`` (3x3 screen px -> plane m),
    ``screen_kind`` ("monitor" or "projector"). Display: ``display_gamma``,
    ``display_black`` (fraction of white), ``display_wb`` (B, G, R), ``hotspot``
    (relative fall-off to the corners), ``view_falloff`` (exponent of cos of the
    viewing angle), ``glare`` (strength, image centre u, v, radius px). Room:
    ``wall`` (pattern name, colour, contrast, period m, angle), ``objects``,
    ``ambient`` (room light on reflectance 1 at the screen, display-white units),
    ``light_gradient``, ``light_angle``, ``lamp`` (strength, X, Y, radius m),
    ``ambient_colour``, ``spill`` (screen light on the wall: strength, range m),
    ``light_drift`` (amplitude, period s, phase), ``flicker`` (amplitude, Hz),
    ``window_drift`` (amplitude, period s, phase), ``occluder`` (image polygon
    vertices, reflectance) or None. Camera electronics: ``white_level`` (sensor
    level of the display's white at the screen centre, before auto-exposure),
    ``ae_strength`` (0 locked .. 1 full), ``ae_lag`` (fraction corrected per
    frame), ``exposure_drift`` (amplitude, period s, phase), ``exposure_s``,
    ``readout_s`` (rolling shutter), ``camera_gamma``, ``colour_gain`` (B, G, R),
    ``defocus_px`` (Gaussian sigma), ``flare`` (strength, sigma px), ``chromatic``
    (lateral: R magnified by 1 + c, B by 1 - c), ``bloom`` (strength,
    cross-channel fraction, sigma px), ``bayer``, ``full_well`` (electrons at
    clipping: shot noise), ``read_noise`` (fraction of full scale),
    ``sharpen``, ``compression``; ``supersample`` sub-pixels per side.
    """

    seed: int
    camera: SceneCamera
    R: FloatArray
    t: FloatArray
    screen_px: tuple[int, int]
    screen_m: tuple[float, float]
    Hs: FloatArray
    screen_kind: str
    display_gamma: float
    display_black: float
    display_wb: tuple[float, float, float]
    hotspot: float
    view_falloff: float
    glare: tuple[float, float, float, float]
    surround: tuple[float, float, float, float, float, float]  # frame/bezel: widths + colour
    wall: tuple[str, float, float, float, float, float, float]
    objects: tuple[WallObject, ...]
    ambient: float
    light_gradient: float
    light_angle: float
    lamp: tuple[float, float, float, float]
    ambient_colour: tuple[float, float, float]
    spill: tuple[float, float]
    light_drift: tuple[float, float, float]
    flicker: tuple[float, float]
    window_drift: tuple[float, float, float]
    occluder: tuple[tuple[tuple[float, float], ...], float] | None
    white_level: float
    ae_strength: float
    ae_lag: float
    exposure_drift: tuple[float, float, float]
    exposure_s: float
    readout_s: float
    camera_gamma: float
    colour_gain: tuple[float, float, float]
    defocus_px: float
    flare: tuple[float, float]
    chromatic: float
    bloom: tuple[float, float, float]
    bayer: bool
    full_well: float
    read_noise: float
    sharpen: float
    compression: Compression
    supersample: int
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0
    cropped: bool = False
    extras: dict[str, Any] = field(default_factory=dict, compare=False)

    # ------------------------------------------------------------ truth

    @property
    def size(self) -> tuple[int, int]:
        """Camera image (W, H), px."""
        return self.camera.width, self.camera.height

    def camera_center(self) -> FloatArray:
        """Camera centre in world coordinates (m)."""
        out: FloatArray = -self.R.T @ self.t
        return out

    def screen_to_plane(self, xy: FloatArray) -> FloatArray:
        """Screen px (N, 2) -> plane metres (N, 2)."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        h = np.column_stack([xy + 0.5, np.ones(len(xy))]) @ self.Hs.T
        out: FloatArray = h[:, :2] / h[:, 2:]
        return out

    def plane_to_screen(self, XY: FloatArray) -> FloatArray:
        """Plane metres (N, 2) -> screen px (N, 2)."""
        XY = np.asarray(XY, float).reshape(-1, 2)
        h = np.column_stack([XY, np.ones(len(XY))]) @ np.linalg.inv(self.Hs).T
        out: FloatArray = h[:, :2] / h[:, 2:] - 0.5
        return out

    def normalized_to_screen_matrix(self) -> FloatArray:
        """3x3: undistorted normalized (x, y, 1) -> screen (x + 0.5, y + 0.5, 1), homogeneous."""
        Hp = np.linalg.inv(np.column_stack([self.R[:, 0], self.R[:, 1], self.t]))
        out: FloatArray = np.linalg.inv(self.Hs) @ Hp
        return out

    def image_to_screen(self, uv: FloatArray) -> FloatArray:
        """Image px (N, 2) -> screen px (N, 2), exact; NaN where the ray misses the plane."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        n = self.camera.pixels_to_normalized(uv)
        Hp = np.linalg.inv(np.column_stack([self.R[:, 0], self.R[:, 1], self.t]))
        w = np.column_stack([n, np.ones(len(n))]) @ Hp.T  # plane (X, Y) homogeneous
        with np.errstate(invalid="ignore", divide="ignore"):
            XY = w[:, :2] / w[:, 2:]
            front = w[:, 2] > 0  # the ray's parameter along it is positive
        out = self.plane_to_screen(XY)
        out[~front | ~np.isfinite(out).all(axis=1)] = np.nan
        return out

    def screen_to_image(self, xy: FloatArray) -> FloatArray:
        """Screen px (N, 2) -> image px (N, 2); NaN behind the camera or beyond the lens."""
        XY = self.screen_to_plane(xy)
        Xw = np.column_stack([XY, np.zeros(len(XY))])
        Xc = Xw @ self.R.T + self.t
        front = Xc[:, 2] > 1e-9
        z = np.where(front, Xc[:, 2], 1.0)
        uv = self.camera.normalized_to_pixels(Xc[:, :2] / z[:, None])
        uv[~front] = np.nan
        return uv

    def occluded(self, uv: FloatArray) -> NDArray[np.bool_]:
        """Whether image points (N, 2) lie behind the occluder."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        out = np.zeros(len(uv), bool)
        if self.occluder is None:
            return out
        poly = np.asarray(self.occluder[0], np.float32).reshape(-1, 1, 2)
        for i, (u, v) in enumerate(uv):
            if np.isfinite(u) and np.isfinite(v):
                out[i] = cv2.pointPolygonTest(poly, (float(u), float(v)), False) >= 0
        return out

    def visible(self, xy: FloatArray, radius_px: float = 0.0) -> NDArray[np.bool_]:
        """Whether screen points (N, 2) are in the picture and not occluded; with
        ``radius_px`` > 0 the whole disc of that radius (screen px) must be."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        offs = [(0.0, 0.0)]
        if radius_px > 0:
            a = np.arange(8) * np.pi / 4
            offs += [(radius_px * math.cos(x), radius_px * math.sin(x)) for x in a]
        W, H = self.size
        ok = np.ones(len(xy), bool)
        for dx, dy in offs:
            uv = self.screen_to_image(xy + np.array([dx, dy]))
            with np.errstate(invalid="ignore"):
                inside = (
                    np.isfinite(uv).all(axis=1)
                    & (uv[:, 0] >= 0)
                    & (uv[:, 0] <= W - 1)
                    & (uv[:, 1] >= 0)
                    & (uv[:, 1] <= H - 1)
                )
            ok &= inside & ~self.occluded(uv)
        return ok

    def screen_border(self, per_side: int = 64) -> FloatArray:
        """The lit area's outline in screen px (4 per_side, 2), clockwise from top-left."""
        W, H = self.screen_px
        s = np.linspace(0.0, 1.0, per_side, endpoint=False)
        x0, x1, y0, y1 = -0.5, W - 0.5, -0.5, H - 0.5
        return np.concatenate(
            [
                np.column_stack([x0 + s * (x1 - x0), np.full_like(s, y0)]),
                np.column_stack([np.full_like(s, x1), y0 + s * (y1 - y0)]),
                np.column_stack([x1 - s * (x1 - x0), np.full_like(s, y1)]),
                np.column_stack([np.full_like(s, x0), y1 - s * (y1 - y0)]),
            ]
        )

    def screen_fully_visible(self) -> bool:
        """Whether the whole lit area is in the picture and nothing occludes its outline."""
        return bool(self.visible(self.screen_border()).all())

    def row_time(self, v: FloatArray | float) -> FloatArray:
        """Start of exposure of image row(s) ``v`` after the frame's start (s): rolling shutter."""
        return np.asarray(v, float) * (self.readout_s / self.camera.height)

    def classes(self) -> dict[str, str]:
        """Labels for reporting by class: resolution, codec, screen kind, lens, angle, light."""
        W, H = self.size
        k1 = self.camera.k1
        ang = max(abs(self.yaw_deg), abs(self.pitch_deg))
        return {
            "camera": ">=640x480" if W * H >= 640 * 480 else "<640x480",
            "resolution": f"{W}x{H}",
            "codec": self.compression.codec,
            "screen": self.screen_kind,
            "k1": "barrel<-0.15" if k1 < -0.15 else ("pincushion>0.05" if k1 > 0.05 else "mild"),
            "angle": "<15deg" if ang < 15 else ("15-25deg" if ang < 25 else ">=25deg"),
            "exposure": "auto" if self.ae_strength > 0 else "locked",
            "occluder": "yes" if self.occluder is not None else "no",
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters (numpy arrays as lists)."""
        d: dict[str, Any] = {}
        for k, v in self.__dict__.items():
            if isinstance(v, np.ndarray):
                d[k] = v.tolist()
            elif k == "camera" or k == "compression":
                d[k] = asdict(v)
            elif k == "objects":
                d[k] = [asdict(o) for o in v]
            else:
                d[k] = v
        d["camera_matrix"] = [
            [self.camera.fx, 0.0, self.camera.cx],
            [0.0, self.camera.fy, self.camera.cy],
            [0.0, 0.0, 1.0],
        ]
        d["distortion"] = [self.camera.k1, self.camera.k2, 0.0, 0.0, 0.0]
        d["camera_center_m"] = self.camera_center().tolist()
        return d


# ---------------------------------------------------------------- drawing a scene


def _draw_lens(rng: np.random.Generator, ranges: SceneRanges, size: tuple[int, int]) -> SceneCamera:
    W, H = size
    for _ in range(200):
        hfov = math.radians(rng.uniform(*ranges.hfov_deg))
        fx = (W / 2) / math.tan(hfov / 2)
        fy = fx * (1.0 + rng.uniform(-0.01, 0.01))
        cx = (W - 1) / 2 + rng.uniform(-0.03, 0.03) * W
        cy = (H - 1) / 2 + rng.uniform(-0.03, 0.03) * H
        k1 = float(rng.uniform(*ranges.k1))
        k2 = float(rng.uniform(-0.25, 0.25) * abs(k1) + (0.4 * k1 * k1 if k1 < 0 else 0.0))
        cam = SceneCamera(W, H, fx, fy, cx, cy, k1, k2)
        corners = np.array([[-0.5, -0.5], [W - 0.5, -0.5], [W - 0.5, H - 0.5], [-0.5, H - 0.5]])
        rd = np.hypot((corners[:, 0] - cx) / fx, (corners[:, 1] - cy) / fy).max()
        lim = cam.radius_limit()
        d_lim = float(cam.distort(np.array([min(lim, 50.0)]))[0])
        if rd < 0.97 * d_lim:
            r_corner = float(cam.undistort_radius(np.array([rd]))[0])
            if math.degrees(math.atan(r_corner)) < 72:  # the image corners within 72 deg
                return cam
    raise RuntimeError("no lens found in the ranges")  # pragma: no cover


def _pose_at(
    cam: SceneCamera,
    centre: FloatArray,
    aim: FloatArray,
    yaw: float,
    pitch: float,
    roll: float,
    dist: float,
) -> tuple[FloatArray, FloatArray]:
    C = centre + dist * np.array(
        [math.sin(yaw) * math.cos(pitch), -math.sin(pitch), -math.cos(yaw) * math.cos(pitch)]
    )
    pose = look_at(C, aim, roll_deg=roll)
    R = pose.R.copy()
    return R, -R @ C


def _draw_geometry(
    rng: np.random.Generator, ranges: SceneRanges, cam: SceneCamera, partial: ScreenScene
) -> tuple[FloatArray, FloatArray, bool, float, float, float]:
    """Pose: yaw, pitch, roll, aim and a distance giving the drawn fill."""
    Wm, Hm = partial.screen_m
    cropped = bool(rng.random() < ranges.crop_prob)
    for _ in range(100):
        yaw = math.radians(rng.uniform(-ranges.yaw_deg, ranges.yaw_deg))
        pitch = math.radians(rng.uniform(-ranges.pitch_deg, ranges.pitch_deg))
        roll = float(rng.uniform(-ranges.roll_deg, ranges.roll_deg))
        centre = np.array([Wm / 2, Hm / 2, 0.0])
        aim = centre + np.array([rng.uniform(-0.08, 0.08) * Wm, rng.uniform(-0.08, 0.08) * Hm, 0])
        fill = rng.uniform(1.05, 1.35) if cropped else rng.uniform(*ranges.fill)

        def extent(
            d: float,
            yaw: float = yaw,
            pitch: float = pitch,
            roll: float = roll,
            centre: FloatArray = centre,
            aim: FloatArray = aim,
        ) -> float:
            R, t = _pose_at(cam, centre, aim, yaw, pitch, roll, d)
            sc = replace(partial, R=R, t=t)
            b = sc.screen_to_image(sc.screen_border(32))
            if not np.isfinite(b).all():
                return math.inf
            fw = (b[:, 0].max() - b[:, 0].min()) / cam.width
            fh = (b[:, 1].max() - b[:, 1].min()) / cam.height
            return float(max(fw, fh))

        lo, hi = 0.05, 60.0
        for _ in range(50):
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if extent(mid) > fill else (lo, mid)
        R, t = _pose_at(cam, centre, aim, yaw, pitch, roll, hi)
        sc = replace(partial, R=R, t=t)
        if cropped or sc.visible(sc.screen_border(32)).all():
            return R, t, cropped, math.degrees(yaw), math.degrees(pitch), roll
    raise RuntimeError("no pose found in the ranges")  # pragma: no cover


def _colour(
    rng: np.random.Generator, lo: float, hi: float, sat: float
) -> tuple[float, float, float]:
    """A BGR reflectance: grey level in [lo, hi], each channel tinted by up to +-sat."""
    base = rng.uniform(lo, hi)
    b, g, r = (float(np.clip(base * x, 0.0, 1.0)) for x in 1.0 + rng.uniform(-sat, sat, 3))
    return b, g, r


def _draw_objects(
    rng: np.random.Generator, ranges: SceneRanges, Wm: float, Hm: float, margin: float
) -> tuple[WallObject, ...]:
    """Doors, windows, frames, posters, whiteboards, monitors beside the screen (plane m)."""
    sizes = {
        "door": ((0.8, 1.0), (1.9, 2.2)),
        "window": ((0.6, 1.6), (0.8, 1.5)),
        "picture": ((0.2, 0.9), (0.2, 0.7)),
        "poster": ((0.4, 0.8), (0.55, 1.1)),
        "monitor_off": ((0.35, 0.75), (0.22, 0.45)),
        "monitor_on": ((0.35, 0.75), (0.22, 0.45)),
        "whiteboard": ((0.9, 1.8), (0.6, 1.2)),
        "shelf": ((0.5, 1.5), (0.03, 0.06)),
    }
    weights = {
        "door": 1.0,
        "window": 1.2,
        "picture": 2.0,
        "poster": 1.5,
        "monitor_off": 1.2,
        "monitor_on": 0.7,
        "whiteboard": 0.8,
        "shelf": 0.8,
    }
    n = int(rng.integers(ranges.distractors[0], ranges.distractors[1] + 1))
    placed: list[WallObject] = []
    keep_out = [(-margin, -margin, Wm + margin, Hm + margin)]
    S = max(Wm, Hm)
    for _k in range(60):
        if len(placed) >= n:
            break
        kind = _choice(rng, weights)
        (w0, w1), (h0, h1) = sizes[kind]
        w, h = rng.uniform(w0, w1), rng.uniform(h0, h1)
        gap = margin + rng.uniform(0.002, 0.6) * S * (0.3 if rng.random() < 0.5 else 1.0)
        side = int(rng.integers(4))
        if side == 0:  # left
            x1 = -gap
            x0 = x1 - w
            y0 = rng.uniform(-h, Hm) if kind != "door" else Hm + margin + 0.3 - h
        elif side == 1:  # right
            x0 = Wm + gap
            x1 = x0 + w
            y0 = rng.uniform(-h, Hm) if kind != "door" else Hm + margin + 0.3 - h
        elif side == 2:  # above
            y1 = -gap
            y0 = y1 - h
            x0 = rng.uniform(-w, Wm)
        else:  # below
            y0 = Hm + gap
            x0 = rng.uniform(-w, Wm)
        x1, y1 = x0 + w, y0 + h
        if any(x0 < b[2] and x1 > b[0] and y0 < b[3] and y1 > b[1] for b in keep_out):
            continue
        frame = {
            "door": rng.uniform(0.04, 0.09),
            "window": rng.uniform(0.04, 0.08),
            "picture": rng.uniform(0.01, 0.06),
            "poster": 0.0,
            "monitor_off": rng.uniform(0.008, 0.03),
            "monitor_on": rng.uniform(0.008, 0.03),
            "whiteboard": rng.uniform(0.01, 0.025),
            "shelf": 0.0,
        }[kind]
        dark = rng.random() < 0.5
        fcol = _colour(rng, 0.03, 0.15, 0.1) if dark else _colour(rng, 0.55, 0.9, 0.08)
        body = {
            "door": _colour(rng, 0.2, 0.85, 0.25),
            "window": (0.5, 0.5, 0.5),
            "picture": _colour(rng, 0.1, 0.8, 0.4),
            "poster": _colour(rng, 0.75, 0.92, 0.05),
            "monitor_off": _colour(rng, 0.02, 0.05, 0.05),
            "monitor_on": _colour(rng, 0.02, 0.05, 0.05),
            "whiteboard": _colour(rng, 0.8, 0.92, 0.03),
            "shelf": _colour(rng, 0.1, 0.7, 0.3),
        }[kind]
        emission = 0.0
        if kind == "window":
            emission = float(rng.uniform(0.3, 4.0))
        elif kind == "monitor_on":
            emission = float(rng.uniform(0.3, 1.0))
        placed.append(
            WallObject(
                kind, x0, y0, x1, y1, frame, fcol, body, emission, int(rng.integers(1 << 30))
            )
        )
        keep_out.append((x0, y0, x1, y1))
    return tuple(placed)


def _draw_occluder(
    rng: np.random.Generator, scene: ScreenScene
) -> tuple[tuple[tuple[float, float], ...], float]:
    """An image-space silhouette (head and shoulders, a chair back, a plant) over the screen."""
    corners = scene.screen_to_image(
        np.array([[0.0, 0.0], [scene.screen_px[0] - 1.0, scene.screen_px[1] - 1.0]])
    )
    (u0, v0), (u1, v1) = corners
    u_lo, u_hi = sorted((u0, u1))
    v_lo, v_hi = sorted((v0, v1))
    W, H = scene.size
    kind = int(rng.integers(3))
    cu = rng.uniform(u_lo + 0.1 * (u_hi - u_lo), u_hi - 0.1 * (u_hi - u_lo))
    size = rng.uniform(0.12, 0.3) * (u_hi - u_lo)
    a = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    if kind == 0:  # head and shoulders from the bottom of the picture
        top = rng.uniform(v_lo + 0.45 * (v_hi - v_lo), v_hi - 0.1 * (v_hi - v_lo))
        head = [(cu + 0.35 * size * math.cos(x), top + 0.45 * size * (1 + math.sin(x))) for x in a]
        head = [p for p in head if p[1] <= top + 0.8 * size]
        sh = top + 0.8 * size
        pts = [(cu - 1.1 * size, H + 5.0), (cu - 1.0 * size, sh + 0.2 * size)]
        pts += [
            (cu - 0.5 * size, sh),
            *sorted(head, key=lambda p: math.atan2(p[1] - top, p[0] - cu)),
        ]
        pts += [
            (cu + 0.5 * size, sh),
            (cu + 1.0 * size, sh + 0.2 * size),
            (cu + 1.1 * size, H + 5.0),
        ]
    elif kind == 1:  # a chair back / a box from the bottom
        top = rng.uniform(v_lo + 0.55 * (v_hi - v_lo), v_hi - 0.05 * (v_hi - v_lo))
        pts = [(cu - size, H + 5.0), (cu - size, top), (cu + size, top), (cu + size, H + 5.0)]
    else:  # a plant: a blob
        cv = rng.uniform(v_lo + 0.5 * (v_hi - v_lo), v_hi)
        rad = size * (1 + 0.25 * np.sin(5 * a + rng.uniform(0, 6)))
        pts = [
            (cu + r * math.cos(x), cv + 0.8 * r * math.sin(x)) for r, x in zip(rad, a, strict=True)
        ]
    refl = float(rng.uniform(0.05, 0.7))
    clipped = tuple((float(np.clip(u, -5, W + 5)), float(np.clip(v, -5, H + 5))) for u, v in pts)
    return clipped, refl


def draw_scene(seed: int, ranges: SceneRanges = DEFAULT_RANGES) -> ScreenScene:
    """Draw every parameter of a scene from ``seed`` (deterministic)."""
    rng = np.random.default_rng([int(seed), 2012])
    size = ranges.resolutions[int(rng.integers(len(ranges.resolutions)))]
    cam = _draw_lens(rng, ranges, size)
    sr = ranges.screen_resolutions
    if rng.random() < ranges.first_screen_weight or len(sr) == 1:
        screen_px = sr[0]
    else:
        screen_px = sr[1 + int(rng.integers(len(sr) - 1))]
    kind = _choice(rng, dict(ranges.screen_kinds))
    SW, SH = screen_px
    Wm = float(rng.uniform(0.3, 0.8) if kind == "monitor" else rng.uniform(1.0, 3.0))
    Hm = Wm * SH / SW
    if kind == "projector":
        k = rng.uniform(-0.025, 0.025, (4, 2)) * np.array([Wm, Hm])
        dst = np.array([[0, 0], [Wm, 0], [Wm, Hm], [0, Hm]]) + k
        src = np.array([[0, 0], [SW, 0], [SW, SH], [0, SH]], float)
        hs_cv = cv2.getPerspectiveTransform(src.astype(np.float32), dst.astype(np.float32))
        Hs: FloatArray = np.asarray(hs_cv, np.float64)
        # fabric border, black frame
        surround = (
            float(rng.uniform(0.02, 0.15)),
            float(rng.uniform(0.0, 0.08) if rng.random() < 0.6 else 0.0),
            *_colour(rng, 0.65, 0.9, 0.03),
            float(rng.uniform(0.02, 0.12)),
        )
        margin = surround[0] + surround[1] + 0.03
    else:
        Hs = np.diag([Wm / SW, Hm / SH, 1.0]).astype(np.float64)
        bezel = float(rng.uniform(0.004, 0.035))
        bcol = (
            _colour(rng, 0.02, 0.1, 0.05)
            if rng.random() < 0.6
            else (
                _colour(rng, 0.4, 0.6, 0.03)
                if rng.random() < 0.5
                else _colour(rng, 0.75, 0.9, 0.02)
            )
        )
        surround = (bezel, float(rng.uniform(0.0, 0.04)), *bcol, float(rng.uniform(0.01, 0.06)))
        margin = bezel + surround[1] + 0.01
    objects = _draw_objects(rng, ranges, Wm, Hm, margin)
    comp_name = _choice(rng, dict(ranges.codecs))
    if comp_name == "jpeg":
        comp = Compression(
            "jpeg",
            quality=int(rng.integers(45, 96)),
            chroma=str(rng.choice(["420", "422", "444"], p=[0.7, 0.2, 0.1])),
        )
    elif comp_name == "h264":
        comp = Compression("h264", bits_per_pixel=float(rng.uniform(0.03, 0.15)), gop=30)
    elif comp_name == "mpeg4":
        comp = Compression("mpeg4", bits_per_pixel=float(rng.uniform(0.06, 0.3)), gop=30)
    else:
        comp = Compression("none")
    W, H = size
    supersample = 4 if W * H <= 130_000 else (3 if W * H <= 600_000 else 2)
    ae = rng.random() < ranges.ae_prob
    wall_kind = _choice(
        rng,
        {"plain": 1.0, "stripes": 1.0, "checks": 0.7, "bricks": 0.8, "noise": 1.0, "tiles": 0.6},
    )
    partial = ScreenScene(
        seed=int(seed),
        camera=cam,
        R=np.eye(3),
        t=np.array([0.0, 0.0, 1.0]),
        screen_px=screen_px,
        screen_m=(Wm, Hm),
        Hs=Hs,
        screen_kind=kind,
        display_gamma=float(rng.uniform(1.8, 2.4)),
        display_black=float(
            rng.uniform(0.002, 0.03) if kind == "monitor" else rng.uniform(0.005, 0.05)
        ),
        display_wb=tuple(float(x) for x in 1.0 + rng.uniform(-0.08, 0.04, 3)),  # type: ignore[arg-type]
        hotspot=float(rng.uniform(0.0, 0.12) if kind == "monitor" else rng.uniform(0.1, 0.5)),
        view_falloff=float(rng.uniform(0.0, 1.5) if kind == "monitor" else rng.uniform(0.0, 0.5)),
        glare=(0.0, 0.0, 0.0, 1.0),
        surround=surround,  # type: ignore[arg-type]
        wall=(
            wall_kind,
            *_colour(rng, 0.25, 0.9, 0.2),
            float(rng.uniform(0.1, 0.8)),
            float(rng.uniform(0.02, 0.4) * max(Wm, Hm)),
            float(rng.uniform(0, math.pi)),
        ),  # type: ignore[arg-type]
        objects=objects,
        ambient=float(np.exp(rng.uniform(math.log(0.02), math.log(0.6)))),
        light_gradient=float(rng.uniform(0.0, 1.5)),
        light_angle=float(rng.uniform(0, 2 * math.pi)),
        lamp=(
            float(rng.uniform(0.0, 1.5)),
            float(rng.uniform(-0.5, 1.5) * Wm),
            float(rng.uniform(-0.8, 0.5) * Hm),
            float(rng.uniform(0.2, 1.0) * max(Wm, Hm)),
        ),
        ambient_colour=tuple(float(x) for x in 1.0 + rng.uniform(-0.2, 0.2, 3)),  # type: ignore[arg-type]
        spill=(float(rng.uniform(0.0, 0.1)), float(rng.uniform(0.1, 0.5) * max(Wm, Hm))),
        light_drift=(
            float(rng.uniform(0, 0.12)),
            float(rng.uniform(2, 20)),
            float(rng.uniform(0, 6.3)),
        ),
        flicker=(
            float(rng.uniform(0, 0.12) if rng.random() < 0.5 else 0.0),
            float(rng.choice([100.0, 120.0])),
        ),
        window_drift=(
            float(rng.uniform(0, 0.3)),
            float(rng.uniform(1, 10)),
            float(rng.uniform(0, 6.3)),
        ),
        occluder=None,
        white_level=float(rng.uniform(0.55, 1.05)),
        ae_strength=float(rng.uniform(0.3, 1.0)) if ae else 0.0,
        ae_lag=float(rng.uniform(0.2, 0.9)),
        exposure_drift=(
            float(rng.uniform(0, 0.06)),
            float(rng.uniform(2, 15)),
            float(rng.uniform(0, 6.3)),
        ),
        exposure_s=float(np.exp(rng.uniform(math.log(0.002), math.log(0.033)))),
        readout_s=float(rng.uniform(0.0, 0.03)),
        camera_gamma=float(rng.uniform(1.8, 2.4)),
        colour_gain=tuple(float(x) for x in 1.0 + rng.uniform(-0.15, 0.15, 3)),  # type: ignore[arg-type]
        defocus_px=float(rng.uniform(0.0, 1.5) if rng.random() < 0.7 else 0.0),
        flare=(float(rng.uniform(0.0, 0.03)), float(rng.uniform(5.0, 30.0))),
        chromatic=float(rng.uniform(0.0, 0.0015)),
        bloom=(
            float(rng.uniform(0.0, 0.6)),
            float(rng.uniform(0.0, 0.4)),
            float(rng.uniform(0.8, 4.0)),
        ),
        bayer=bool(rng.random() < 0.5),
        full_well=float(np.exp(rng.uniform(math.log(200), math.log(4000)))),
        read_noise=float(rng.uniform(0.5, 3.0) / 255),
        sharpen=float(rng.uniform(0.0, 1.0) if rng.random() < 0.6 else 0.0),
        compression=comp,
        supersample=supersample,
    )
    R, t, cropped, yaw, pitch, roll = _draw_geometry(rng, ranges, cam, partial)
    scene = replace(partial, R=R, t=t, cropped=cropped, yaw_deg=yaw, pitch_deg=pitch, roll_deg=roll)
    centre = scene.screen_to_image(np.array([[SW / 2, SH / 2]]))[0]
    if kind == "monitor" and rng.random() < 0.4:
        g = (
            float(rng.uniform(0.02, 0.25)),
            float(centre[0] + rng.uniform(-0.4, 0.4) * W),
            float(centre[1] + rng.uniform(-0.4, 0.4) * H),
            float(rng.uniform(0.05, 0.3) * W),
        )
        scene = replace(scene, glare=g)
    if rng.random() < ranges.occluder_prob:
        scene = replace(scene, occluder=_draw_occluder(rng, scene))
    return scene


# ---------------------------------------------------------------- painting the wall


def _smooth_noise(seed: int, shape: tuple[int, int], cells: tuple[int, int]) -> F32:
    rng = np.random.default_rng([seed, 99])
    small = rng.normal(0.0, 1.0, (cells[1], cells[0])).astype(np.float32)
    out = cv2.resize(small, (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)
    return np.asarray(out, np.float32)


def _texture_sample(tex: F32, u: F32, v: F32) -> F32:
    """Sample texture ``tex`` (h, w[, 3]) at normalized coordinates u, v in [0, 1]
    (any equal shapes; sampled in rows of 1024 points, cv2.remap's size limit)."""
    h, w = tex.shape[:2]
    shape = u.shape
    m = u.size
    rows = max(1, math.ceil(m / 1024))
    mx = np.zeros(rows * 1024, np.float32)
    my = np.zeros(rows * 1024, np.float32)
    mx[:m] = u.ravel() * (w - 1)
    my[:m] = v.ravel() * (h - 1)
    out = cv2.remap(
        tex,
        mx.reshape(rows, 1024),
        my.reshape(rows, 1024),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    out = np.asarray(out, np.float32).reshape(rows * 1024, *tex.shape[2:])[:m]
    return out.reshape(*shape, *tex.shape[2:])


def _picture_texture(seed: int, kind: str) -> F32:
    """Content of a picture, poster or live monitor (reflectance or emission 0..1, BGR)."""
    rng = np.random.default_rng([seed, 7])
    n = 256
    if kind == "poster":
        img = np.full((n, n, 3), 0.9, np.float32)
        y = 30
        while y < n - 20:
            x1 = int(rng.uniform(80, 230))
            cv2.rectangle(img, (20, y), (x1, y + int(rng.uniform(3, 7))), (0.05, 0.05, 0.05), -1)
            y += int(rng.uniform(10, 18))
        cv2.rectangle(img, (20, 4), (236, 22), tuple(float(x) for x in rng.uniform(0, 1, 3)), -1)
        return img
    if kind == "monitor_on":  # a desktop: bright windows, dark bar, icons
        img = np.full((n, n, 3), 0.0, np.float32)
        img[:] = rng.uniform(0.1, 0.6, 3).astype(np.float32)
        for _ in range(int(rng.integers(1, 4))):
            x0, y0 = int(rng.uniform(0, 150)), int(rng.uniform(0, 150))
            cv2.rectangle(
                img,
                (x0, y0),
                (x0 + int(rng.uniform(60, 200)), y0 + int(rng.uniform(40, 150))),
                (1.0, 1.0, 1.0),
                -1,
            )
        img[-16:] = 0.05
        return img
    base = cv2.resize(
        rng.uniform(0, 1, (4, 4, 3)).astype(np.float32), (n, n), interpolation=cv2.INTER_CUBIC
    )
    for _ in range(int(rng.integers(3, 9))):
        c = (int(rng.uniform(0, n)), int(rng.uniform(0, n)))
        col = tuple(float(x) for x in rng.uniform(0, 1, 3))
        if rng.random() < 0.5:
            cv2.circle(base, c, int(rng.uniform(5, 60)), col, -1, cv2.LINE_AA)
        else:
            cv2.rectangle(
                base, c, (c[0] + int(rng.uniform(5, 90)), c[1] + int(rng.uniform(5, 90))), col, -1
            )
    return np.clip(base, 0.02, 0.95).astype(np.float32)


def _paint_wall(
    scene: ScreenScene, X: FloatArray, Y: FloatArray
) -> tuple[F32, F32, F32, NDArray[np.bool_]]:
    """Reflectance (..., 3), window emission (..., 3), static emission (..., 3) and the
    wall-pattern mask at plane points X, Y (m)."""
    shape = X.shape
    kind, b, g, r, contrast, period, angle = scene.wall
    base = np.array([b, g, r], np.float32)
    ca, sa = math.cos(angle), math.sin(angle)
    s = (X * ca + Y * sa) / period
    q = (-X * sa + Y * ca) / period
    if kind == "stripes":
        pat = (np.floor(s) % 2).astype(np.float32)
    elif kind == "checks":
        pat = ((np.floor(s) + np.floor(q)) % 2).astype(np.float32)
    elif kind == "bricks":
        row = np.floor(Y / (0.4 * period))
        xx = X / period + 0.5 * (row % 2)
        mortar = (np.abs(Y / (0.4 * period) - row - 0.5) > 0.42) | (
            np.abs(xx - np.floor(xx) - 0.5) > 0.46
        )
        pat = mortar.astype(np.float32)
    elif kind == "tiles":
        fx, fy = X / period, Y / period
        pat = ((np.abs(fx - np.round(fx)) < 0.04) | (np.abs(fy - np.round(fy)) < 0.04)).astype(
            np.float32
        )
    elif kind == "noise":
        tex = _smooth_noise(scene.seed + 5, (512, 512), (64, 64))
        span = 40.0 * period
        pat = np.clip(
            0.5
            + 0.4
            * _texture_sample(
                tex, ((X / span) % 1).astype(np.float32), ((Y / span) % 1).astype(np.float32)
            ),
            0,
            1,
        )
    else:
        pat = np.zeros(shape, np.float32)
    lowf = _smooth_noise(scene.seed + 11, (256, 256), (6, 6))
    S = max(scene.screen_m)
    u = np.clip((X / (8 * S) + 0.5), 0, 1).astype(np.float32)
    v = np.clip((Y / (8 * S) + 0.5), 0, 1).astype(np.float32)
    low = 1.0 + 0.08 * _texture_sample(lowf, u, v)
    refl = base[None, :] * ((1.0 - contrast * pat) * low)[..., None].reshape(-1, 1)
    refl = refl.reshape(*shape, 3).astype(np.float32)
    emit_w = np.zeros((*shape, 3), np.float32)
    emit_s = np.zeros((*shape, 3), np.float32)
    for o in scene.objects:
        inside = (o.x0 <= X) & (o.x1 > X) & (o.y0 <= Y) & (o.y1 > Y)
        if not inside.any():
            continue
        f = o.frame_m
        inner = inside & (o.x0 + f <= X) & (o.x1 - f > X) & (o.y0 + f <= Y) & (o.y1 - f > Y)
        refl[inside & ~inner] = o.frame_colour
        ui = ((X[inner] - o.x0 - f) / max(o.x1 - o.x0 - 2 * f, 1e-6)).astype(np.float32)
        vi = ((Y[inner] - o.y0 - f) / max(o.y1 - o.y0 - 2 * f, 1e-6)).astype(np.float32)
        if o.kind in ("picture", "poster"):
            tex = _picture_texture(o.seed, o.kind)
            refl[inner] = _texture_sample(tex, ui, vi)
        elif o.kind == "window":
            mull = (np.abs(ui - 0.5) < 0.02) | (np.abs(vi - 0.5) < 0.025)
            glass = np.where(mull, 0.0, 1.0).astype(np.float32)
            sky = np.array([1.0, 0.95, 0.85], np.float32) * o.emission
            grad = (1.0 - 0.4 * vi)[:, None] * sky[None, :]
            ew = emit_w[inner]
            ew[:] = grad * glass[:, None]
            emit_w[inner] = ew
            rr = refl[inner]
            rr[:] = np.where(mull[:, None], np.array(o.frame_colour, np.float32), 0.05)
            refl[inner] = rr
        elif o.kind == "monitor_on":
            tex = _picture_texture(o.seed, o.kind)
            emit_s[inner] = _texture_sample(tex, ui, vi) * o.emission
            refl[inner] = o.body_colour
        elif o.kind == "door":
            refl[inner] = o.body_colour
            handle = (
                inner & (np.abs(X - (o.x1 - f - 0.08)) < 0.03) & (np.abs(Y - (o.y0 + 1.0)) < 0.015)
            )
            refl[handle] = (0.7, 0.7, 0.7)
        else:
            refl[inner] = o.body_colour
    # the screen's surroundings: bezel / fabric and frame, and the screen's own surface
    _Wm, _Hm = scene.screen_m
    w_in, w_out, sb, sg, sr, surface = scene.surround
    quad = scene.screen_to_plane(
        np.array(
            [
                [-0.5, -0.5],
                [scene.screen_px[0] - 0.5, -0.5],
                [scene.screen_px[0] - 0.5, scene.screen_px[1] - 0.5],
                [-0.5, scene.screen_px[1] - 0.5],
            ]
        )
    )
    x_lo, y_lo = quad.min(axis=0)
    x_hi, y_hi = quad.max(axis=0)
    outer = (
        (x_lo - w_in - w_out <= X)
        & (x_hi + w_in + w_out > X)
        & (y_lo - w_in - w_out <= Y)
        & (y_hi + w_in + w_out > Y)
    )
    ring = (x_lo - w_in <= X) & (x_hi + w_in > X) & (y_lo - w_in <= Y) & (y_hi + w_in > Y)
    if scene.screen_kind == "projector":
        refl[outer & ~ring] = (0.04, 0.04, 0.04)
        refl[ring] = (sb, sg, sr)  # the fabric, also inside the lit area
    else:
        refl[outer & ~ring] = (0.05, 0.05, 0.05)  # the monitor's rim
        refl[ring] = (sb, sg, sr)  # bezel
        panel = (x_lo <= X) & (x_hi > X) & (y_lo <= Y) & (y_hi > Y)
        refl[panel] = surface
    return refl, emit_w, emit_s, outer


# ---------------------------------------------------------------- the renderer


@dataclass
class FrameInput:
    """One frame of a sequence: what the screen shows (BGR or grey uint8, screen px),
    when (s since the sequence start), and optional extra light on the plane."""

    content: U8
    t: float
    extra_light: ExtraLight | None = None
    extra_light_t: TimedExtraLight | None = None
    extra_light_bbox: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class Capture:
    """A rendered frame: ``image`` (H x W x 3 BGR uint8, compressed), its time ``t`` (s)
    and the ``exposure`` (relative to the scene's base exposure) it was taken with."""

    image: U8
    t: float
    exposure: float


def _display_lut(scene: ScreenScene) -> F32:
    s = np.arange(256, dtype=np.float64) / 255.0
    lin = scene.display_black + (1.0 - scene.display_black) * s**scene.display_gamma
    out = lin[:, None] * np.array(scene.display_wb)[None, :]
    lut: F32 = out.astype(np.float32)  # (256, 3) B, G, R
    return lut


def _wide_blur(img: F32, sigma: float) -> F32:
    """A Gaussian blur of large ``sigma`` (px) computed at a quarter of the resolution."""
    h, w = img.shape[:2]
    k = 4 if sigma >= 8 else 1
    small = cv2.resize(img, (max(1, w // k), max(1, h // k)), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / k)
    return np.asarray(cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR), np.float32)


def _box(x: NDArray[Any], n: int) -> F32:
    """Mean over n x n blocks of the first two axes (the sub-pixels of each pixel)."""
    a = np.asarray(x, np.float32)
    h, w = a.shape[0] // n, a.shape[1] // n
    if n == 1:
        return a
    return np.asarray(cv2.resize(a, (w, h), interpolation=cv2.INTER_AREA), np.float32)


class SceneRenderer:
    """Renders frames of one scene (precomputes the rays' hits, the room, the light fields)."""

    def __init__(self, scene: ScreenScene) -> None:
        self.scene = scene
        n = scene.supersample
        W, H = scene.size
        SW, SH = scene.screen_px
        G = scene.normalized_to_screen_matrix()
        Hp = np.linalg.inv(np.column_stack([scene.R[:, 0], scene.R[:, 1], scene.t]))
        offs = (np.arange(n) + 0.5) / n - 0.5
        us = (np.arange(W)[:, None] + offs[None, :]).ravel()
        rows = (np.arange(H)[:, None] + offs[None, :]).ravel()
        occ_sub = np.zeros((H * n, W * n), np.uint8)
        if scene.occluder is not None:
            pts = (np.asarray(scene.occluder[0]) + 0.5) * n - 0.5
            cv2.fillPoly(occ_sub, [np.round(pts * 16).astype(np.int32)], (1,), cv2.LINE_8, shift=4)
        self.sx = np.empty((H * n, W * n), np.float32)
        self.sy = np.empty((H * n, W * n), np.float32)
        refl = np.zeros((H, W, 3), np.float32)
        emit_w = np.zeros((H, W, 3), np.float32)
        emit_s = np.zeros((H, W, 3), np.float32)
        cover = np.zeros((H, W), np.float32)
        plane = np.zeros((H, W, 2), np.float32)
        band = max(n, (262_144 // max(W * n, 1)) // n * n)
        S = max(scene.screen_m)
        for a in range(0, H * n, band):
            vv, uu = np.meshgrid(rows[a : a + band], us, indexing="ij")
            xy = scene.camera.pixels_to_normalized(np.stack([uu, vv], -1))
            hom = np.stack([xy[..., 0], xy[..., 1], np.ones_like(xy[..., 0])], -1)
            pw = hom @ Hp.T
            ps = hom @ G.T
            ok = np.isfinite(pw).all(axis=-1) & (pw[..., 2] > 0)
            with np.errstate(invalid="ignore", divide="ignore"):
                X = np.where(ok, pw[..., 0] / pw[..., 2], 0.0)
                Y = np.where(ok, pw[..., 1] / pw[..., 2], 0.0)
                sxb = ps[..., 0] / ps[..., 2] - 0.5
                syb = ps[..., 1] / ps[..., 2] - 0.5
            far = ok & (np.hypot(X - scene.screen_m[0] / 2, Y - scene.screen_m[1] / 2) < 30 * S)
            occ = occ_sub[a : a + band].astype(bool)
            vis = far & ~occ
            self.sx[a : a + band] = np.where(vis, sxb, _OFF)
            self.sy[a : a + band] = np.where(vis, syb, _OFF)
            rf, ew, es, _ = _paint_wall(scene, X, Y)
            m = vis[..., None].astype(np.float32)
            inside = vis & (sxb >= -0.5) & (sxb <= SW - 0.5) & (syb >= -0.5) & (syb <= SH - 0.5)
            hb = vv.shape[0] // n
            r0 = a // n

            refl[r0 : r0 + hb] = _box(rf * m, n)
            emit_w[r0 : r0 + hb] = _box(ew * m, n)
            emit_s[r0 : r0 + hb] = _box(es * m, n)
            cover[r0 : r0 + hb] = _box(inside, n)
            plane[r0 : r0 + hb] = _box(np.stack([X, Y], -1), n)
        self.occ_alpha = cv2.resize(
            occ_sub.astype(np.float32), (W, H), interpolation=cv2.INTER_AREA
        ).astype(np.float32)
        del occ_sub
        self.refl, self.emit_w, self.emit_s, self.cover = refl, emit_w, emit_s, cover
        self._light_fields(plane.astype(np.float64))
        self.lut = _display_lut(scene)
        # content pre-filter: one mip level for the screen px per sub-pixel
        area = float(np.count_nonzero(cover > 0.5))
        per = math.sqrt(SW * SH / max(area * n * n, 1.0))
        self.mip = max(0, math.floor(math.log2(max(per, 1.0))))
        self._ca_maps = self._chromatic_maps()
        # the last content's screen light: slides hold still for many frames
        self._screen_cache: tuple[bytes, F32, float] | None = None

    def _light_fields(self, plane: FloatArray) -> None:
        """Room light, spill, display gain and glare at the pixels (``plane``: each
        pixel's mean hit on the plane, m)."""
        sc = self.scene
        W, H = sc.size
        vv, uu = np.mgrid[0:H, 0:W].astype(np.float64)
        X, Y = plane[..., 0], plane[..., 1]
        xy = sc.plane_to_screen(plane.reshape(-1, 2))
        Wm, Hm = sc.screen_m
        S = max(Wm, Hm)
        nx, ny = (X - Wm / 2) / S, (Y - Hm / 2) / S
        ramp = np.clip(math.cos(sc.light_angle) * nx + math.sin(sc.light_angle) * ny, -4, 4)
        amb = sc.ambient * np.exp(sc.light_gradient * ramp)
        ls, lx, ly, lr = sc.lamp
        amb = amb + sc.ambient * ls * np.exp(-((X - lx) ** 2 + (Y - ly) ** 2) / (2 * lr * lr))
        self.ambient = (amb[..., None] * np.array(sc.ambient_colour)[None, None, :]).astype(
            np.float32
        )
        strength, reach = sc.spill
        dx = np.maximum(np.maximum(-X, X - Wm), 0.0)
        dy = np.maximum(np.maximum(-Y, Y - Hm), 0.0)
        self.spill = (strength * np.exp(-np.hypot(dx, dy) / reach) * (1.0 - self.cover)).astype(
            np.float32
        )
        # display gain over the screen: hot spot, viewing angle
        sxp = np.nan_to_num(xy[:, 0].reshape(H, W), nan=0.0)
        syp = np.nan_to_num(xy[:, 1].reshape(H, W), nan=0.0)
        SW, SH = sc.screen_px
        qx, qy = (sxp + 0.5) / SW * 2 - 1, (syp + 0.5) / SH * 2 - 1
        gain = 1.0 - sc.hotspot * (qx**2 + (qy * SH / SW) ** 2) / (1 + (SH / SW) ** 2)
        C = sc.camera_center()
        d = np.stack([X - C[0], Y - C[1], -np.full_like(X, C[2])], -1)
        cosang = np.abs(d[..., 2]) / np.linalg.norm(d, axis=-1)
        c0 = abs(C[2]) / np.linalg.norm(np.array([Wm / 2, Hm / 2, 0.0]) - C)
        gain *= (cosang / c0) ** sc.view_falloff
        self.display_gain = np.clip(gain, 0.0, 4.0).astype(np.float32)
        g, gu, gv, gr = sc.glare
        self.glare = (
            g * np.exp(-((uu - gu) ** 2 + (vv - gv) ** 2) / (2 * gr * gr)) * self.cover
        ).astype(np.float32)
        self.occ_light = (
            (sc.occluder[1] if sc.occluder is not None else 0.0)
            * np.float32(sc.ambient)
            * (1.0 + 0.2 * np.cos(uu / W * 6.0 + vv / H * 3.0)).astype(np.float32)
        )
        # base exposure: the display's white at the screen centre reaches white_level
        c = sc.screen_to_image(np.array([[SW / 2, SH / 2]]))[0]
        ci, cj = int(np.clip(round(c[1]), 0, H - 1)), int(np.clip(round(c[0]), 0, W - 1))
        centre_white = float(self.display_gain[ci, cj]) + float(
            self.ambient[ci, cj, 1] * self.refl[ci, cj, 1]
        )
        self.base_exposure = sc.white_level / max(centre_white, 1e-3)

    def _chromatic_maps(self) -> tuple[F32, F32, F32, F32] | None:
        sc = self.scene
        c = sc.chromatic
        if c <= 0:
            return None
        W, H = sc.size
        vv, uu = np.mgrid[0:H, 0:W].astype(np.float32)
        cx, cy = np.float32(sc.camera.cx), np.float32(sc.camera.cy)
        # red focuses larger: the red image is magnified by 1 + c, blue by 1 - c
        rx = cx + (uu - cx) / np.float32(1 + c)
        ry = cy + (vv - cy) / np.float32(1 + c)
        bx = cx + (uu - cx) / np.float32(1 - c)
        by = cy + (vv - cy) / np.float32(1 - c)
        return rx, ry, bx, by

    # ------------------------------------------------------------ one frame

    def light_factor(self, t: float) -> tuple[F32, float]:
        """Room light over the rows (H,) at frame time t (drift and flicker averaged over the
        exposure, with the rows' rolling-shutter times) and the windows' factor."""
        sc = self.scene
        H = sc.camera.height
        tr = t + sc.row_time(np.arange(H, dtype=np.float64))
        a, period, ph = sc.light_drift
        f = 1.0 + a * np.sin(2 * np.pi * tr / period + ph)
        amp, hz = sc.flicker
        if amp > 0:
            w, e = 2 * np.pi * hz, sc.exposure_s
            f = f + amp * (np.cos(w * tr) - np.cos(w * (tr + e))) / (w * e)
        wa, wp, wph = sc.window_drift
        win = 1.0 + wa * math.sin(2 * np.pi * t / wp + wph) * math.sin(0.37 * t + wph)
        return f.astype(np.float32), float(win)

    def radiance(
        self,
        content: U8,
        t: float = 0.0,
        *,
        extra_light: ExtraLight | None = None,
        extra_light_t: TimedExtraLight | None = None,
        extra_light_bbox: tuple[float, float, float, float] | None = None,
        motion_samples: int = 1,
    ) -> F32:
        """Linear radiance reaching the sensor (H, W, 3), display-white units, before optics."""
        sc = self.scene
        SW, SH = sc.screen_px
        c = np.asarray(content)
        if c.shape[:2] != (SH, SW) or c.dtype != np.uint8:
            raise ValueError(
                f"screen content {c.shape} {c.dtype}: expected uint8 {SH}x{SW} (grey) "
                f"or {SH}x{SW}x3"
            )
        key = hashlib.blake2b(np.ascontiguousarray(c).data, digest_size=16).digest() + bytes(
            str(c.shape), "ascii"
        )
        if self._screen_cache is not None and self._screen_cache[0] == key:
            screen, mean_lum = self._screen_cache[1], self._screen_cache[2]
        else:
            screen, mean_lum = self._screen_light(c)
            self._screen_cache = (key, screen, mean_lum)
        rowf, winf = self.light_factor(t)
        illum = self.ambient * rowf[:, None, None] + (self.spill * mean_lum)[..., None]
        L = screen * self.display_gain[..., None] + self.refl * illum
        L += self.emit_w * np.float32(winf) + self.emit_s + self.glare[..., None]
        L += (self.occ_alpha * self.occ_light * rowf[:, None])[..., None]
        if extra_light is not None or extra_light_t is not None:
            self._add_extra(L, t, extra_light, extra_light_t, extra_light_bbox, motion_samples)
        return np.asarray(L, np.float32)

    def _screen_light(self, c: U8) -> tuple[F32, float]:
        """The display's light (H, W, 3) at the pixels for screen content ``c`` (before
        the display gain), and the content's mean linear green (for the spill light)."""
        n = self.scene.supersample
        if c.ndim == 2:
            c = np.repeat(c[..., None], 3, axis=2)
        lin = np.asarray(cv2.LUT(np.ascontiguousarray(c), self.lut.reshape(256, 1, 3)), np.float32)
        mean_lum = float(lin[..., 1].mean())
        scale = 2**self.mip
        for _ in range(self.mip):
            lin = np.asarray(cv2.pyrDown(lin), np.float32)
        lin = np.asarray(
            cv2.copyMakeBorder(lin, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=(0.0, 0.0, 0.0)),
            np.float32,
        )
        # cv2.pyrDown centres output pixel i on input pixel 2i: level-L x = x / 2^L
        mx = self.sx / np.float32(scale) + np.float32(1.0)
        my = self.sy / np.float32(scale) + np.float32(1.0)
        ss = cv2.remap(
            lin,
            mx,
            my,
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=(0.0, 0.0, 0.0),
        )
        del mx, my
        screen = _box(ss, n)
        return screen, mean_lum

    def _window(self, bbox: tuple[float, float, float, float] | None) -> tuple[int, int, int, int]:
        sc = self.scene
        W, H = sc.size
        if bbox is None:
            return 0, H, 0, W
        x0, y0, x1, y1 = bbox
        s = np.linspace(0, 1, 16)
        pts = np.concatenate(
            [
                np.column_stack([x0 + s * (x1 - x0), np.full_like(s, y0)]),
                np.column_stack([x0 + s * (x1 - x0), np.full_like(s, y1)]),
                np.column_stack([np.full_like(s, x0), y0 + s * (y1 - y0)]),
                np.column_stack([np.full_like(s, x1), y0 + s * (y1 - y0)]),
            ]
        )
        uv = sc.screen_to_image(pts)
        if not np.isfinite(uv).all():
            return 0, H, 0, W
        c0 = max(math.floor(uv[:, 0].min()) - 2, 0)
        c1 = min(math.ceil(uv[:, 0].max()) + 3, W)
        r0 = max(math.floor(uv[:, 1].min()) - 2, 0)
        r1 = min(math.ceil(uv[:, 1].max()) + 3, H)
        return r0, max(r1, r0), c0, max(c1, c0)

    def _add_extra(
        self,
        L: F32,
        t: float,
        fn: ExtraLight | None,
        fn_t: TimedExtraLight | None,
        bbox: tuple[float, float, float, float] | None,
        motion_samples: int,
    ) -> None:
        sc = self.scene
        n = sc.supersample
        r0, r1, c0, c1 = self._window(bbox)
        if r1 <= r0 or c1 <= c0:
            return
        sx = self.sx[r0 * n : r1 * n, c0 * n : c1 * n]
        sy = self.sy[r0 * n : r1 * n, c0 * n : c1 * n]
        ok = sx > _OFF / 2
        acc = np.zeros((*sx.shape, 3), np.float64)
        if ok.any():
            pts = np.column_stack([sx[ok], sy[ok]]).astype(np.float64)
            if fn_t is None:
                assert fn is not None
                acc[ok] = np.asarray(fn(pts), np.float64)
            else:
                rows = (np.arange(r0 * n, r1 * n) + 0.5) / n - 0.5
                tr = t + sc.row_time(rows)
                tt = np.broadcast_to(tr[:, None], sx.shape)[ok]
                k = max(1, int(motion_samples))
                for j in range(k):
                    acc[ok] += np.asarray(fn_t(pts, tt + (j + 0.5) / k * sc.exposure_s), np.float64)
                acc[ok] /= k
        h, w = r1 - r0, c1 - c0
        L[r0:r1, c0:c1] += acc.reshape(h, n, w, n, 3).mean(axis=(1, 3)).astype(np.float32)

    def sensor(self, L: F32, exposure: float, frame_seed: int) -> U8:
        """The camera's 8-bit picture of radiance ``L`` at relative ``exposure`` (before
        compression): optics, exposure and colour gains, per-channel clipping with
        blooming, noise, Bayer demosaicing, gamma, sharpening."""
        sc = self.scene
        rng = np.random.default_rng([sc.seed, int(frame_seed), 31337])
        img = L
        if sc.defocus_px > 0.05:
            img = np.asarray(cv2.GaussianBlur(img, (0, 0), sc.defocus_px), np.float32)
        fs, fsig = sc.flare
        if fs > 0:
            img = img * np.float32(1 - fs) + _wide_blur(img, fsig) * np.float32(fs)
        if self._ca_maps is not None:
            rx, ry, bx, by = self._ca_maps
            b_ch = cv2.remap(img[..., 0], bx, by, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            r_ch = cv2.remap(img[..., 2], rx, ry, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            img = np.stack([b_ch, img[..., 1], r_ch], -1)
        gain = np.float32(self.base_exposure * exposure) * np.array(sc.colour_gain, np.float32)
        S = img * gain
        bs, bx_frac, bsig = sc.bloom
        excess = np.maximum(S - 1.0, 0.0)
        if bs > 0 and float(excess.max()) > 0:
            spread = cv2.GaussianBlur(excess, (0, 0), bsig)
            cross = spread.mean(axis=2, keepdims=True)
            S = S + np.float32(bs) * ((1 - bx_frac) * spread + bx_frac * cross)
        if sc.bayer:
            H, W = S.shape[:2]
            mosaic = np.empty((H, W), np.float32)  # BGGR: B at (0, 0), R at (1, 1)
            mosaic[0::2, 0::2] = S[0::2, 0::2, 0]
            mosaic[0::2, 1::2] = S[0::2, 1::2, 1]
            mosaic[1::2, 0::2] = S[1::2, 0::2, 1]
            mosaic[1::2, 1::2] = S[1::2, 1::2, 2]
            mosaic = self._noise(mosaic, rng)
            v = np.clip(mosaic, 0.0, 1.0) ** np.float32(1.0 / sc.camera_gamma)
            raw = np.clip(v * 255.0 + 0.5, 0, 255).astype(np.uint8)
            out = cv2.cvtColor(raw, cv2.COLOR_BayerRG2BGR)  # OpenCV names it from row 1
        else:
            S = self._noise(S, rng)
            v = np.clip(S, 0.0, 1.0) ** np.float32(1.0 / sc.camera_gamma)
            out = np.clip(v * 255.0 + 0.5, 0, 255).astype(np.uint8)
        if sc.sharpen > 0:
            f = out.astype(np.float32)
            f = f + np.float32(sc.sharpen) * (f - cv2.GaussianBlur(f, (0, 0), 1.0))
            out = np.clip(f + 0.5, 0, 255).astype(np.uint8)
        return np.asarray(out, np.uint8)

    def _noise(self, S: F32, rng: np.random.Generator) -> F32:
        sc = self.scene
        sigma = np.sqrt(
            np.maximum(S, 0.0) / np.float32(sc.full_well) + np.float32(sc.read_noise**2)
        )
        out = S + rng.standard_normal(S.shape, dtype=np.float32) * sigma.astype(np.float32)
        return np.asarray(out, np.float32)

    def render(
        self,
        content: U8,
        t: float = 0.0,
        *,
        exposure: float = 1.0,
        frame_seed: int = 0,
        extra_light: ExtraLight | None = None,
        extra_light_t: TimedExtraLight | None = None,
        extra_light_bbox: tuple[float, float, float, float] | None = None,
        motion_samples: int = 1,
    ) -> U8:
        """One frame (H x W x 3 BGR uint8, before compression) of ``content`` at time ``t``.

        ``exposure`` is relative to the scene's base exposure (what auto-exposure set);
        ``frame_seed`` with the scene's seed fixes the noise.
        """
        L = self.radiance(
            content,
            t,
            extra_light=extra_light,
            extra_light_t=extra_light_t,
            extra_light_bbox=extra_light_bbox,
            motion_samples=motion_samples,
        )
        return self.sensor(L, exposure * self.exposure_drift(t), frame_seed)

    def exposure_drift(self, t: float) -> float:
        """The slow drift of the exposure at time t (a factor near 1)."""
        a, period, ph = self.scene.exposure_drift
        return 1.0 + a * math.sin(2 * math.pi * t / period + ph)

    def metered(self, L: F32) -> float:
        """The scene brightness auto-exposure meters: mean green radiance, centre-weighted."""
        H, W = L.shape[:2]
        g = L[..., 1]
        wgt = np.ones((H, W), np.float32)
        wgt[H // 4 : 3 * H // 4, W // 4 : 3 * W // 4] = 3.0
        return float((g * wgt).sum() / wgt.sum())


_RENDERERS: dict[int, tuple[ScreenScene, SceneRenderer]] = {}


def renderer_for(scene: ScreenScene) -> SceneRenderer:
    """A :class:`SceneRenderer` for ``scene``, cached (the last two scenes)."""
    key = id(scene)
    hit = _RENDERERS.get(key)
    if hit is not None and hit[0] is scene:
        return hit[1]
    r = SceneRenderer(scene)
    if len(_RENDERERS) >= 2:
        _RENDERERS.pop(next(iter(_RENDERERS)))
    _RENDERERS[key] = (scene, r)
    return r


def _expose(
    scene: ScreenScene,
    r: SceneRenderer,
    radiances: Iterable[tuple[F32, float]],
    frame_seed: int,
    on_frame: Callable[[int, float, U8], None] | None = None,
) -> tuple[list[U8], list[float], list[float]]:
    """Auto-exposure over a stream of (radiance, t): meter each frame, correct a
    fraction ``ae_lag`` of the log error towards ``ae_strength log(reference / metered)``
    (the reference: the first frame), clamp to 1/8 .. 8, add the drift, sense.
    ``on_frame(frame_seed, exposure, image)``: called after each frame is sensed, with
    the sensor's seed and the exposure it used (drift included): a twin radiance
    sensed with both gets the same exposure and the same noise."""
    images: list[U8] = []
    times: list[float] = []
    exps: list[float] = []
    log_e = 0.0
    ref: float | None = None
    for i, (L, t) in enumerate(radiances):
        m = r.metered(L)
        if ref is None:
            ref = m
        if scene.ae_strength > 0 and i > 0:
            target = scene.ae_strength * math.log(ref / max(m, 1e-6))
            target = float(np.clip(target, math.log(1 / 8), math.log(8)))
            log_e += scene.ae_lag * (target - log_e)
        e = math.exp(log_e)
        exposure = e * r.exposure_drift(t)
        images.append(r.sensor(L, exposure, frame_seed + i))
        if on_frame is not None:
            on_frame(frame_seed + i, exposure, images[-1])
        times.append(t)
        exps.append(e)
    return images, times, exps


def render_sequence(
    scene: ScreenScene,
    frames: Iterable[FrameInput],
    *,
    fps: float = 30.0,
    motion_samples: int = 1,
    compress: bool = True,
    frame_seed: int = 0,
) -> list[Capture]:
    """Render and compress a sequence of :class:`FrameInput`: auto-exposure with the
    scene's strength and lag (its reference: the first frame's brightness), exposure
    drift, then the scene's compression over the whole stream at ``fps``."""
    r = renderer_for(scene)

    def radiances() -> Iterable[tuple[F32, float]]:
        for f in frames:
            L = r.radiance(
                f.content,
                f.t,
                extra_light=f.extra_light,
                extra_light_t=f.extra_light_t,
                extra_light_bbox=f.extra_light_bbox,
                motion_samples=motion_samples,
            )
            yield L, f.t

    images, times, exps = _expose(scene, r, radiances(), frame_seed)
    out = compress_frames(images, scene.compression, fps=fps) if compress else images
    return [Capture(img, t, e) for img, t, e in zip(out, times, exps, strict=True)]


def capture_stills(
    scene: ScreenScene,
    contents: Sequence[U8],
    *,
    frames_per_still: int = 3,
    interval_s: float = 1.0,
    fps: float = 30.0,
    frame_seed: int = 0,
    compress: bool = True,
) -> list[U8]:
    """Captures of displayed contents (calibration patterns), as a user takes them.

    Content k is shown at ``k * interval_s`` and the camera keeps streaming; the
    last of ``frames_per_still`` frames after each change is kept (auto-exposure
    has partly settled; one compressed stream for all). The room light is that of
    the kept frame's time for all frames of a content (each gets its own noise).
    """
    r = renderer_for(scene)
    n = max(1, int(frames_per_still))

    def radiances() -> Iterable[tuple[F32, float]]:
        for k, c in enumerate(contents):
            t_keep = k * interval_s + (n - 1) / fps
            L = r.radiance(c, t_keep)
            for j in range(n):
                yield L, k * interval_s + j / fps

    images, _, _ = _expose(scene, r, radiances(), frame_seed)
    out = compress_frames(images, scene.compression, fps=fps) if compress else images
    return [out[(k + 1) * n - 1] for k in range(len(contents))]
