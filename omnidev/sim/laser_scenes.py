"""Randomized laser-pointer scenes with exact truth: a fixed camera watching a screen
on which a hand-held laser spot moves, each scene drawn from one seed.

A scene (:func:`draw_laser_scene`) fixes the camera (resolution 320x240 to
1920x1080, lens, pose), the light (exposure, room light, display and camera
gamma, auto-exposure drift, sensor noise, compression) and the laser:

- colour: red or green;
- look (:data:`LOOKS`): ``white-core`` (the other channels clip too at the
  centre), ``colour-only`` (only the laser channel clips; at the brightest pixel
  of a spot on a dark slide the others stay at 90-230, as a webcam shows a red
  laser), ``bloom`` (colour-only with a wide glow around the clipped blob);
- size: the clipped blob of a still spot 2-20 camera px across; power 2-60 times
  the clipping level;
- the hand: minimum-jerk moves at 150-1500 screen px/s (per 1920 px), holds with
  tremor, jumps, stretches with the laser off (>= 20 % of the frames); the
  spot's path within each exposure (1/500-1/30 s) blurs it; rows are read
  one after the other (rolling shutter).

Slides (:mod:`omnidev.sim.laser_content`) of one class per scene (dark, white,
saturated) change every 1-4 s and are full of look-alikes.

Light model (per colour channel, linear light in units of the camera's clipping
level): ``E (ambient + display(content)) + laser``, clipped at 1 per channel,
with sensor noise (read + shot), then the camera's gamma and 8 bits. The
display turns content values c into light ``(c / 255) ^ gamma_display``. The
laser's light on the screen plane at distance d (screen px) from its centre is
``P (exp(-d^2 / 2 sigma^2) + bloom exp(-d / bloom_px))`` in the laser channel
and ``crosstalk`` times that in the two others (a colour camera's response to
one wavelength), averaged over the exposure. A clipped pixel spills part of its
excess into its neighbours (sensor blooming).

Truth per frame (:class:`LaserTruth`): whether the laser is on, the spot's
position in screen and image pixels (the mean of its path over the exposure of
the rows it lies on: the centroid of its light), whether it is visible at all
(it raises the laser channel by >= 25 grey levels somewhere: a spot on content
that already clips that channel is not), and the tolerance of the issue 12
acceptance: 1.5 screen px, or the screen length of 0.5 camera px where that
is larger.

Frames: image pixels (u, v) and screen pixels (x, y) with the centre of the
top-left pixel at (0, 0) (docs/conventions.md), as :mod:`omnidev.sim.screen`.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.sim.laser_content import SLIDE_CLASSES, LaserSlide
from omnidev.sim.screen import (
    ScreenRig,
    _prepare,
    image_to_screen,
    screen_border_image,
    screen_rig,
    screen_to_image,
)

FloatArray = NDArray[np.float64]
LOOKS = ("white-core", "colour-only", "bloom")
COLOURS = ("red", "green")
COMPRESSIONS = ("none", "mjpeg", "mpeg4", "h264")
SIZES = ((320, 240), (640, 360), (640, 480), (800, 600), (1280, 720), (1920, 1080))
_LASER_CH = {"red": 2, "green": 1}  # BGR index of the laser channel
LEAD_IN = 8  # frames at the start with the laser off
VISIBLE_RISE = 25  # grey levels the laser must add somewhere for the spot to be visible


def resolution_class(width: int) -> str:
    """``low`` up to 640 px wide, ``mid`` up to 1280, ``high`` above."""
    return "low" if width <= 640 else ("mid" if width <= 1280 else "high")


@dataclass(frozen=True)
class LaserSceneParams:
    """Everything one laser scene is drawn from (units in each field's comment)."""

    seed: int
    width: int  # camera image, px
    height: int
    k1: float  # radial distortion (k2 = k1^2 / 2)
    tilt_deg: float  # camera to the side of the screen's normal
    colour: str  # "red" | "green"
    look: str  # one of LOOKS
    power: float  # the laser channel's peak on the screen, times the clipping level
    crosstalk: float  # the other channels' response to the laser, relative
    spot_px: float  # clipped diameter of a still spot, camera px
    sigma_px: float  # the beam's Gaussian sigma, screen px
    bloom: float  # glow amplitude relative to the peak
    bloom_px: float  # glow decay length, screen px
    sensor_bloom: float  # fraction of a clipped pixel's excess spilled to neighbours
    exposure: float  # display white -> camera linear (1 = clips)
    ambient: float  # room light relative to the rendered room's
    drift: float  # auto-exposure drift amplitude (relative)
    exposure_s: float  # exposure time, s
    rolling_s: float  # time between the first and the last row's exposure, s
    gamma_display: float
    gamma_camera: float
    read_noise: float  # linear, units of the clipping level
    shot_noise: float  # sigma^2 = read^2 + shot^2 * level
    compression: str  # one of COMPRESSIONS
    quality: int  # JPEG quality (mjpeg) or kbit/s (mpeg4, h264)
    slide_class: str  # one of SLIDE_CLASSES
    video: bool  # slides hold a video window
    fps: float
    frames: int
    tremor_px: float  # hand tremor amplitude, screen px (per 1920)
    speed: float  # mean move speed, screen px/s (per 1920)

    def classes(self) -> dict[str, str]:
        """The scene's class in each reported axis."""
        return {
            "look": self.look,
            "colour": self.colour,
            "compression": self.compression,
            "slide": self.slide_class,
            "resolution": resolution_class(self.width),
        }

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_laser_scene(seed: int, *, frames: int = 90) -> LaserSceneParams:
    """The parameters of laser scene ``seed`` (see the module docstring for the ranges)."""
    rng = np.random.default_rng([seed, 1212])
    W, H = SIZES[int(rng.integers(len(SIZES)))]
    k1 = float(rng.uniform(-0.35, 0.2))
    tilt = float(rng.uniform(0.0, 25.0))
    colour = COLOURS[int(rng.integers(2))]
    look = LOOKS[int(rng.integers(3))]
    power = _loguniform(rng, 2.0, 60.0)
    if look == "white-core":
        others = _loguniform(rng, 1.3, 8.0)
    else:
        others = float(rng.uniform(0.12, 0.75))
    crosstalk = min(0.5, others / power)
    spot_px = _loguniform(rng, 2.0, 20.0)
    bloom = _loguniform(rng, 0.03, 0.2) / power if look == "bloom" else 0.0
    exposure = (
        float(rng.uniform(0.45, 1.0)) if rng.random() < 0.85 else float(rng.uniform(1.0, 1.3))
    )
    exposure_s = min(_loguniform(rng, 1 / 500, 1 / 30), 1 / 30)
    compression = COMPRESSIONS[int(rng.integers(4))]
    pixels = W * H / (1280 * 720)
    if compression == "mjpeg":
        quality = int(rng.integers(50, 96))
    elif compression == "mpeg4":
        quality = int(_loguniform(rng, 1500, 5000) * max(pixels, 0.15))
    elif compression == "h264":
        quality = int(_loguniform(rng, 700, 3000) * max(pixels, 0.15))
    else:
        quality = 0
    params = LaserSceneParams(
        seed=seed,
        width=W,
        height=H,
        k1=k1,
        tilt_deg=tilt,
        colour=colour,
        look=look,
        power=power,
        crosstalk=crosstalk,
        spot_px=spot_px,
        sigma_px=0.0,  # set below from the camera's scale
        bloom=bloom,
        bloom_px=0.0,
        sensor_bloom=float(rng.uniform(0.0, 0.15)),
        exposure=exposure,
        ambient=float(rng.uniform(0.1, 1.0)),
        drift=float(rng.uniform(0.0, 0.1)),
        exposure_s=exposure_s,
        rolling_s=float(rng.uniform(0.0, 0.03)) if rng.random() < 0.7 else 0.0,
        gamma_display=float(rng.uniform(1.8, 2.4)),
        gamma_camera=float(rng.uniform(1.8, 2.4)),
        read_noise=float(rng.uniform(0.002, 0.012)),
        shot_noise=float(rng.uniform(0.0, 0.04)),
        compression=compression,
        quality=quality,
        slide_class=SLIDE_CLASSES[int(rng.integers(3))],
        video=bool(rng.random() < 0.5),
        fps=30.0,
        frames=frames,
        tremor_px=_loguniform(rng, 0.3, 3.0),
        speed=_loguniform(rng, 150.0, 1500.0),
    )
    rig = laser_rig(params)
    scale = _screen_per_image_px(rig)
    sigma = params.spot_px * scale / (2.0 * math.sqrt(2.0 * math.log(params.power)))
    return _replace(params, sigma_px=sigma, bloom_px=sigma * float(rng.uniform(2.5, 6.0)))


def _replace(p: LaserSceneParams, **kw: Any) -> LaserSceneParams:
    d = asdict(p)
    d.update(kw)
    return LaserSceneParams(**d)


def laser_rig(params: LaserSceneParams) -> ScreenRig:
    """The camera and screen of a scene."""
    return screen_rig(
        (params.width, params.height), params.k1, tilt_deg=params.tilt_deg, seed=params.seed
    )


def _screen_per_image_px(rig: ScreenRig) -> float:
    """Screen px per camera px across the screen (its width over its image width)."""
    b = screen_border_image(rig, 64)
    return rig.screen_px[0] / float(b[:, 0].max() - b[:, 0].min())


def tolerance_px(rig: ScreenRig, uv: FloatArray) -> FloatArray:
    """Issue 12's tolerance at image points ``uv`` (N, 2): 1.5 screen px, or the screen
    length of 0.5 camera px (the square root of the local area scale) where larger."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    d = 0.5
    a = image_to_screen(rig, uv + [d, 0]) - image_to_screen(rig, uv - [d, 0])
    b = image_to_screen(rig, uv + [0, d]) - image_to_screen(rig, uv - [0, d])
    area = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])  # screen px^2 per camera px^2
    out: FloatArray = np.maximum(1.5, 0.5 * np.sqrt(area))
    return out


# ------------------------------------------------------------------- the hand


@dataclass(frozen=True)
class _Segment:
    t0: float
    t1: float
    kind: str  # move | hold | off
    a: tuple[float, float]
    b: tuple[float, float]


class LaserPath:
    """The spot's screen position as a function of time (s), and when the laser is on.

    Moves are minimum-jerk; holds stay put; jumps switch position between frames;
    off stretches 0.1-0.6 s; tremor is four sinusoids 4-12 Hz of amplitude
    ``tremor_px`` (scaled to the screen width) added everywhere.
    """

    def __init__(self, params: LaserSceneParams, screen_px: tuple[int, int]) -> None:
        rng = np.random.default_rng([params.seed, 5151])
        W, H = screen_px
        s = W / 1920
        self.width, self.height = W, H
        duration = params.frames / params.fps + 1.0
        margin = 6.0 * s

        def target() -> tuple[float, float]:
            if rng.random() < 0.15:  # near the border
                d = rng.uniform(margin, 25 * s)
                x, y = rng.uniform(d, W - 1 - d), rng.uniform(d, H - 1 - d)
                side = int(rng.integers(4))
                return [(d, y), (W - 1 - d, y), (x, d), (x, H - 1 - d)][side]
            return (float(rng.uniform(30 * s, W - 31 * s)), float(rng.uniform(30 * s, H - 31 * s)))

        segs: list[_Segment] = []
        t, pos = 0.0, target()
        while t < duration:
            kind = str(rng.choice(["move", "hold", "jump", "off"], p=[0.45, 0.25, 0.1, 0.2]))
            if kind == "jump":
                pos = target()
                continue
            if kind == "move":
                q = target()
                dist = math.hypot(q[0] - pos[0], q[1] - pos[1])
                T = max(0.12, dist / (params.speed * s * rng.uniform(0.6, 1.5)))
                segs.append(_Segment(t, t + T, "move", pos, q))
                pos, t = q, t + T
            elif kind == "hold":
                T = float(rng.uniform(0.15, 0.8))
                segs.append(_Segment(t, t + T, "hold", pos, pos))
                t += T
            else:
                T = float(rng.uniform(0.1, 0.6))
                segs.append(_Segment(t, t + T, "off", pos, pos))
                pos, t = target(), t + T
        self.segments = segs
        self._starts = np.array([g.t0 for g in segs])
        self.freq = rng.uniform(4.0, 12.0, (4, 2))
        self.phase = rng.uniform(0, 2 * math.pi, (4, 2))
        self.amp = params.tremor_px * s / 2.0
        self.power_phase = float(rng.uniform(0, 2 * math.pi))
        self.power_freq = float(rng.uniform(0.2, 1.0))
        self._min_off = max(1, math.ceil(0.2 * params.frames))
        self._fps = params.fps
        self._frames = params.frames
        self._forced_off = self._force_off(rng)

    def _segment(self, t: float) -> _Segment:
        k = int(np.searchsorted(self._starts, t, side="right")) - 1
        return self.segments[max(0, min(k, len(self.segments) - 1))]

    def _force_off(self, rng: np.random.Generator) -> set[int]:
        """Frames switched off on top of the off segments until >= 20 % are off."""
        off = {i for i in range(self._frames) if self._segment(i / self._fps).kind == "off"}
        forced: set[int] = set()
        while len(off | forced) < self._min_off:
            k = int(rng.integers(self._frames))
            forced.update(range(k, min(self._frames, k + int(rng.integers(3, 10)))))
        return forced

    def on(self, index: int) -> bool:
        """Whether the laser is on during frame ``index`` (constant over a frame); off for
        the first :data:`LEAD_IN` frames (the camera sees the bare screen first)."""
        if index < LEAD_IN or index in self._forced_off:
            return False
        return self._segment(index / self._fps).kind != "off"

    def position(self, t: FloatArray) -> FloatArray:
        """Screen positions (N, 2) at times ``t`` (N,), s (tremor included)."""
        t = np.asarray(t, float).reshape(-1)
        out = np.empty((t.size, 2))
        for i, ti in enumerate(t):
            g = self._segment(float(ti))
            if g.kind == "move":
                tau = min(1.0, max(0.0, (ti - g.t0) / (g.t1 - g.t0)))
                m = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
                out[i] = (g.a[0] + (g.b[0] - g.a[0]) * m, g.a[1] + (g.b[1] - g.a[1]) * m)
            else:
                out[i] = g.a
        trem = self.amp * np.sin(2 * np.pi * self.freq[None] * t[:, None, None] + self.phase[None])
        out += trem.sum(axis=1)
        out[:, 0] = np.clip(out[:, 0], 1.0, self.width - 2.0)
        out[:, 1] = np.clip(out[:, 1], 1.0, self.height - 2.0)
        return out

    def power(self, t: float) -> float:
        """Relative laser power at time ``t`` (a slow +-12 % wobble: hand angle, battery)."""
        return 1.0 + 0.12 * math.sin(2 * math.pi * self.power_freq * t + self.power_phase)


# ------------------------------------------------------------------- truth


@dataclass(frozen=True)
class LaserTruth:
    """The truth of one frame (screen px and image px; see the module docstring)."""

    index: int
    on: bool
    xy: tuple[float, float] | None  # screen px
    uv: tuple[float, float] | None  # image px
    visible: bool
    tol_px: float  # screen px
    speed_px_s: float  # screen px per second at mid-exposure
    slide_change: bool  # the content changed to a new slide on this frame

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


# ------------------------------------------------------------------- rendering


@dataclass
class _Camera:
    """Per-scene rendering state (interim renderer on omnidev.sim.screen's geometry)."""

    rig: ScreenRig
    params: LaserSceneParams
    mapx: NDArray[np.float32]
    mapy: NDArray[np.float32]
    gain: NDArray[np.float32]  # (H, W, 3) display light -> camera linear at exposure 1
    offset: NDArray[np.float32]  # (H, W, 3) the room at exposure 1
    vign: NDArray[np.float32]
    lut_display: NDArray[np.uint16]  # content value -> linear * 65535
    lut_camera: NDArray[np.uint8]  # linear * 4095 -> 8 bits


_SS = 3  # the geometry maps' supersampling (omnidev.sim.screen.SUPERSAMPLE)
_P_WHITE = 172.0  # omnidev.sim.screen's projector white level


def _camera(rig: ScreenRig, params: LaserSceneParams) -> _Camera:
    prep = _prepare(rig)
    gain = prep.gain * np.float32(255.0 / _P_WHITE)
    offset = prep.offset * np.float32(params.ambient / _P_WHITE)
    lut_d = np.round(((np.arange(256) / 255.0) ** params.gamma_display) * 65535).astype(np.uint16)
    lut_c = np.round(255.0 * (np.arange(4096) / 4095.0) ** (1.0 / params.gamma_camera))
    return _Camera(
        rig,
        params,
        prep.mapx,
        prep.mapy,
        gain.astype(np.float32),
        offset.astype(np.float32),
        prep.vign,
        lut_d,
        lut_c.astype(np.uint8),
    )


def _display_light(
    cam: _Camera, lin_content: NDArray[np.uint16], rows: slice
) -> NDArray[np.float32]:
    """The display's light (linear, 0..1 per channel) seen by camera rows ``rows``;
    ``lin_content`` is the content through the display's gamma, padded by 1 px."""
    r0, r1 = rows.start * _SS, rows.stop * _SS
    ss = cv2.remap(
        lin_content, cam.mapx[r0:r1], cam.mapy[r0:r1], cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT, borderValue=0,
    )  # fmt: skip
    w = cam.rig.width
    out = cv2.resize(ss, (w, rows.stop - rows.start), interpolation=cv2.INTER_AREA)
    res: NDArray[np.float32] = out.astype(np.float32) * np.float32(1 / 65535)
    return res


def _spot_window(
    cam: _Camera, centre: FloatArray, reach: float
) -> tuple[int, int, int, int] | None:
    """Camera rows r0:r1, columns c0:c1 covering screen points within ``reach`` of the
    path points ``centre`` (N, 2)."""
    lo, hi = centre.min(axis=0) - reach, centre.max(axis=0) + reach
    xs = np.linspace(lo[0], hi[0], 5)
    ys = np.linspace(lo[1], hi[1], 5)
    gx, gy = np.meshgrid(xs, ys)
    uv = screen_to_image(cam.rig, np.column_stack([gx.ravel(), gy.ravel()]))
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    if len(uv) == 0:
        return None
    W, H = cam.rig.width, cam.rig.height
    c0 = max(math.floor(uv[:, 0].min()) - 2, 0)
    c1 = min(math.ceil(uv[:, 0].max()) + 3, W)
    r0 = max(math.floor(uv[:, 1].min()) - 2, 0)
    r1 = min(math.ceil(uv[:, 1].max()) + 3, H)
    if c1 <= c0 or r1 <= r0:
        return None
    return r0, r1, c0, c1


class LaserScene:
    """A drawn scene: :meth:`frames` yields (BGR image, truth) for every frame."""

    def __init__(self, params: LaserSceneParams) -> None:
        self.params = params
        self.rig = laser_rig(params)
        self.path = LaserPath(params, self.rig.screen_px)
        rng = np.random.default_rng([params.seed, 3131])
        changes, t = [], 0.0
        duration = params.frames / params.fps
        while t < duration:
            changes.append(t)
            t += float(rng.uniform(1.0, 4.0))
        self._changes = np.array(changes)
        self._slide_seeds = [int(x) for x in rng.integers(0, 2**31, len(changes))]
        self._ae_phase = float(rng.uniform(0, 2 * math.pi))

    def slide_at(self, t: float) -> int:
        return int(np.searchsorted(self._changes, t, side="right")) - 1

    def exposure_at(self, t: float) -> float:
        p = self.params
        return p.exposure * (1.0 + p.drift * math.sin(2 * math.pi * 0.25 * t + self._ae_phase))

    def _row_time(self, v: float) -> float:
        """Exposure-centre time offset of image row ``v`` from the frame's time, s."""
        return self.params.rolling_s * (v / max(1, self.rig.height - 1) - 0.5)

    def _truth(self, i: int, change: bool) -> tuple[LaserTruth, FloatArray | None]:
        p = self.params
        t = i / p.fps
        if not self.path.on(i):
            return LaserTruth(i, False, None, None, False, 1.5, 0.0, change), None
        k = 16
        offs = (np.arange(k) + 0.5) / k - 0.5
        # the row the spot lies on sets its exposure time (rolling shutter): iterate twice
        xy = self.path.position(np.array([t]))[0]
        for _ in range(2):
            uv = screen_to_image(self.rig, xy[None])[0]
            tr = t + self._row_time(float(uv[1]))
            samples = self.path.position(tr + offs * p.exposure_s)
            xy = samples.mean(axis=0)
        uv = screen_to_image(self.rig, xy[None])[0]
        v1 = self.path.position(np.array([tr - 0.005, tr + 0.005]))
        speed = float(np.hypot(*(v1[1] - v1[0]))) / 0.01
        tol = float(tolerance_px(self.rig, uv[None])[0])
        truth = LaserTruth(
            i, True, (float(xy[0]), float(xy[1])), (float(uv[0]), float(uv[1])), True, tol, speed,
            change,
        )  # fmt: skip
        return truth, samples

    def _laser_light(
        self, cam: _Camera, win: tuple[int, int, int, int], t: float, power: float
    ) -> NDArray[np.float32]:
        """The laser's light (h, w, 3) over window rows r0:r1, cols c0:c1 (camera linear,
        units of the clipping level at exposure 1), with the rolling shutter and the
        path within each row's exposure."""
        p = self.params
        r0, r1, c0, c1 = win
        n = 2
        offs = (np.arange(n) + 0.5) / n - 0.5
        us = (np.arange(c0, c1)[:, None] + offs[None, :]).ravel()
        vs = (np.arange(r0, r1)[:, None] + offs[None, :]).ravel()
        vv, uu = np.meshgrid(vs, us, indexing="ij")
        sxy = image_to_screen(self.rig, np.column_stack([uu.ravel(), vv.ravel()]))
        sxy = np.nan_to_num(sxy, nan=-1e6).reshape(vv.shape + (2,))
        # exposure samples for each image row band (8 bands over the window)
        k = 12
        eo = (np.arange(k) + 0.5) / k - 0.5
        level = np.zeros(vv.shape)
        bands = np.array_split(np.arange(vv.shape[0]), min(8, vv.shape[0]))
        sig2 = 2.0 * p.sigma_px**2
        for rows in bands:
            vmid = float(vs[rows].mean())
            times = t + self._row_time(vmid) + eo * p.exposure_s
            centres = self.path.position(times)
            sx, sy = sxy[rows, :, 0], sxy[rows, :, 1]
            acc = np.zeros(sx.shape)
            for cx, cy in centres:
                d2 = (sx - cx) ** 2 + (sy - cy) ** 2
                acc += np.exp(-d2 / sig2)
                if p.bloom > 0:
                    acc += p.bloom * np.exp(-np.sqrt(d2) / p.bloom_px)
            level[rows] = acc / k
        h, w = r1 - r0, c1 - c0
        level = level.reshape(h, n, w, n).mean(axis=(1, 3)) * p.power * power
        level *= cam.vign[r0:r1, c0:c1]
        weights = np.full(3, p.crosstalk)
        weights[_LASER_CH[p.colour]] = 1.0
        out: NDArray[np.float32] = (level[..., None] * weights).astype(np.float32)
        return out

    def _to_8bit(self, cam: _Camera, lin: NDArray[np.float32]) -> NDArray[np.uint8]:
        idx = np.clip(lin * 4095.0 + 0.5, 0, 4095).astype(np.int16)
        out: NDArray[np.uint8] = cam.lut_camera[idx]
        return out

    def raw_frames(self) -> Iterator[tuple[NDArray[np.uint8], LaserTruth]]:
        """Frames before compression (BGR uint8) with their truth."""
        p = self.params
        cam = _camera(self.rig, p)
        H = self.rig.height
        SW, SH = self.rig.screen_px
        slide: LaserSlide | None = None
        lin_content = np.zeros((0, 0, 3), np.uint16)
        static = np.zeros((0, 0, 3), np.float32)
        last = -1
        cv2.setRNGSeed(p.seed * 7919 + 17)
        noise = np.empty((H, self.rig.width, 3), np.float32)
        c = _LASER_CH[p.colour]
        for i in range(p.frames):
            t = i / p.fps
            which = self.slide_at(t)
            change = which != last and i > 0
            if which != last:
                slide = LaserSlide(
                    p.slide_class, SW, SH, p.colour, self._slide_seeds[which], p.video
                )
                lin_content = cv2.copyMakeBorder(
                    cam.lut_display[slide.base], 1, 1, 1, 1, cv2.BORDER_REPLICATE
                )
                static = cam.offset + cam.gain * _display_light(cam, lin_content, slice(0, H))
            last = which
            assert slide is not None
            E = np.float32(self.exposure_at(t))
            if slide.animated:  # re-render the camera rows the moving parts touch
                disp = static.copy()
                content = slide.frame(t)
                boxes = slide.changed_boxes(t)
                saved = []
                for x0, y0, x1, y1 in boxes:
                    saved.append(lin_content[y0 + 1 : y1 + 1, x0 + 1 : x1 + 1].copy())
                    lin_content[y0 + 1 : y1 + 1, x0 + 1 : x1 + 1] = cam.lut_display[
                        content[y0:y1, x0:x1]
                    ]
                for r in self._rows_of(cam, boxes):
                    disp[r] = cam.offset[r] + cam.gain[r] * _display_light(cam, lin_content, r)
                for (x0, y0, x1, y1), old in zip(boxes, saved, strict=True):
                    lin_content[y0 + 1 : y1 + 1, x0 + 1 : x1 + 1] = old
                lin = disp
                lin *= E
            else:
                lin = static * E
            truth, _ = self._truth(i, change)
            if truth.on:
                reach = 3.5 * p.sigma_px + (6.0 * p.bloom_px if p.bloom > 0 else 0.0)
                span = self.path.position(
                    t + np.linspace(-0.5, 0.5, 5) * (p.exposure_s + p.rolling_s)
                )
                win = _spot_window(cam, span, reach + 2.0)
                visible = False
                if win is not None:
                    r0, r1, c0, c1 = win
                    light = self._laser_light(cam, win, t, self.path.power(t))
                    before = self._to_8bit(cam, np.minimum(lin[r0:r1, c0:c1, c], 1.0))
                    lin[r0:r1, c0:c1] += light
                    after = self._to_8bit(cam, np.minimum(lin[r0:r1, c0:c1, c], 1.0))
                    visible = int((after.astype(np.int16) - before).max()) >= VISIBLE_RISE
                    if p.sensor_bloom > 0:  # a share of each clipped pixel's excess spills
                        g0, g1 = max(0, r0 - 6), min(H, r1 + 6)
                        h0, h1 = max(0, c0 - 6), min(self.rig.width, c1 + 6)
                        excess = np.maximum(lin[g0:g1, h0:h1] - 1.0, 0.0)
                        spill = cv2.GaussianBlur(excess, (0, 0), 1.5)
                        lin[g0:g1, h0:h1] += np.float32(p.sensor_bloom) * spill
                if not visible:
                    truth = _replace_truth(truth, visible=False)
            np.minimum(lin, 1.0, out=lin)
            sigma = cv2.sqrt(lin * np.float32(p.shot_noise**2) + np.float32(p.read_noise**2))
            cv2.randn(noise, 0.0, 1.0)
            lin += noise * sigma
            yield self._to_8bit(cam, lin), truth

    def _rows_of(self, cam: _Camera, boxes: list[tuple[int, int, int, int]]) -> list[slice]:
        """Camera row ranges covering screen boxes (x0, y0, x1, y1)."""
        out: list[slice] = []
        H = cam.rig.height
        for x0, y0, x1, y1 in boxes:
            xs = np.linspace(x0, x1, 5)
            pts = np.array([[x, y] for x in xs for y in (y0, y1)], float)
            uv = screen_to_image(cam.rig, pts)
            uv = uv[np.all(np.isfinite(uv), axis=1)]
            if len(uv) == 0:
                continue
            r0 = max(0, math.floor(uv[:, 1].min()) - 2)
            r1 = min(H, math.ceil(uv[:, 1].max()) + 3)
            if r1 > r0:
                out.append(slice(r0, r1))
        return out

    def frames(self) -> Iterator[tuple[NDArray[np.uint8], LaserTruth]]:
        """The camera's frames as the detector gets them (compressed as the scene says)."""
        p = self.params
        if p.compression == "none":
            yield from self.raw_frames()
        elif p.compression == "mjpeg":
            for img, truth in self.raw_frames():
                ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, p.quality])
                assert ok
                yield np.asarray(cv2.imdecode(buf, cv2.IMREAD_COLOR), np.uint8), truth
        else:
            yield from _through_ffmpeg(self.raw_frames(), p)


def _replace_truth(t: LaserTruth, **kw: Any) -> LaserTruth:
    d = asdict(t)
    d.update(kw)
    return LaserTruth(**d)


def _through_ffmpeg(
    frames: Iterator[tuple[NDArray[np.uint8], LaserTruth]], p: LaserSceneParams
) -> Iterator[tuple[NDArray[np.uint8], LaserTruth]]:
    """Encode the frames with ffmpeg (MPEG-4 part 2 or H.264 at ``p.quality`` kbit/s, no
    B-frames, as a webcam streams) and decode them back."""
    ffmpeg = shutil.which("ffmpeg")
    if ffmpeg is None:
        raise RuntimeError("ffmpeg is not installed (scripts/install-system-deps.sh installs it)")
    codec = (
        ["-c:v", "mpeg4", "-bf", "0"]
        if p.compression == "mpeg4"
        else ["-c:v", "libx264", "-preset", "veryfast", "-tune", "zerolatency"]
    )
    truths: list[LaserTruth] = []
    with tempfile.TemporaryDirectory(prefix="omnidev-laser-") as tmp:
        out = Path(tmp) / "scene.mkv"
        cmd = [
            ffmpeg, "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "bgr24",
            "-s", f"{p.width}x{p.height}", "-r", f"{p.fps:g}", "-i", "-", *codec,
            "-b:v", f"{p.quality}k", "-g", "60", "-pix_fmt", "yuv420p", "-y", str(out),
        ]  # fmt: skip
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE)
        assert proc.stdin is not None
        try:
            for img, truth in frames:
                proc.stdin.write(np.ascontiguousarray(img).tobytes())
                truths.append(truth)
        finally:
            proc.stdin.close()
            proc.wait()
        if proc.returncode != 0:
            raise RuntimeError(f"ffmpeg failed encoding scene {p.seed} ({p.compression})")
        cap = cv2.VideoCapture(str(out))
        for truth in truths:
            ok, img = cap.read()
            if not ok:
                raise RuntimeError(f"scene {p.seed}: frame {truth.index} lost in {p.compression}")
            yield np.asarray(img, np.uint8), truth
        cap.release()


def screen_mask(rig: ScreenRig, grow_px: int = 3) -> NDArray[np.bool_]:
    """H x W: the lit screen area in the image, grown by ``grow_px`` (as a calibration's
    screen region)."""
    mask = np.zeros((rig.height, rig.width), np.uint8)
    cv2.fillPoly(mask, [np.round(screen_border_image(rig)).astype(np.int32)], 1)
    k = 2 * grow_px + 1
    out: NDArray[np.bool_] = cv2.dilate(mask, np.ones((k, k), np.uint8)).astype(bool)
    return out
