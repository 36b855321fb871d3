"""Randomized laser-pointer scenes with exact truth: a fixed camera watching a screen
on which a hand-held laser spot moves, each scene drawn from one seed.

The camera, screen, room, light and codec come from
:func:`omnidev.sim.screen_scenes.draw_scene` (the same seed): resolution
320x240 to 1920x1080, lens, pose to 35 degrees, display and camera gamma,
auto-exposure and its drift, noise, Bayer demosaicing, blooming, rolling
shutter, MJPEG / MPEG-4 / H.264. On top of it this module draws the laser and
what the screen shows:

- colour: red or green;
- look (:data:`LOOKS`): ``white-core`` (the other channels clip too at the
  centre), ``colour-only`` (only the laser channel clips; at the brightest pixel
  of a spot on a dark slide the others stay at 90-230, as a webcam shows a red
  laser), ``bloom`` (colour-only with a wide glow around the clipped blob);
- size: the clipped blob of a still spot 2-20 camera px across; power 2-60 times
  the clipping level;
- the hand: minimum-jerk moves at 150-1500 screen px/s (per 1920 px), holds with
  tremor, jumps, stretches with the laser off (>= 20 % of the frames, and the
  first 8: the camera sees the bare screen before the laser comes on); the
  spot's path within each row's exposure blurs it (rolling shutter included);
- slides (:mod:`omnidev.sim.laser_content`) of one class per scene (dark, white,
  saturated) changing every 1-4 s, full of look-alikes, half the scenes with a
  video window.

The laser's light on the screen plane at distance d (screen px) from its centre
is ``P / w (exp(-d^2 / 2 sigma^2) + bloom exp(-d / bloom_px))`` display-white
units in the laser channel (``w``: the scene's white level, so ``P`` is the
peak over the camera's clipping level) and ``crosstalk`` times that in the two
others (a colour camera's response to one wavelength).

Truth per frame (:class:`LaserTruth`): whether the laser is on, the spot's
position in screen and image pixels (the mean of its path over the exposure of
the row it lies on: the centroid of its light), whether it is visible at all
(it raises the camera's laser channel by >= 25 grey levels within its clipped
radius of its centre, judged on the radiance with and without it: a spot on
content that already clips that channel is not), whether it is still visible in
the frame as delivered (``delivered``: the same test on the encoded frame against
the frame rendered and encoded without the laser; a small spot that the codec's
chroma subsampling and quantization wash out is visible but not delivered), and
the tolerance of the issue 12 acceptance in screen px of a 1920x1080 screen: 1.5,
or the screen length of 0.5 camera px where that is larger. Errors are measured in
the same units (x scaled by 1920 / W, y by 1080 / H of the scene's screen), as
``omnidev eval screen`` does.

Frames: image pixels (u, v) and screen pixels (x, y) with the centre of the
top-left pixel at (0, 0) (docs/conventions.md).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.sim.codec import compress_frames
from omnidev.sim.laser_content import SLIDE_CLASSES, LaserSlide
from omnidev.sim.screen_scenes import ScreenScene, _expose, draw_scene, renderer_for

FloatArray = NDArray[np.float64]
LOOKS = ("white-core", "colour-only", "bloom")
COLOURS = ("red", "green")
_LASER_CH = {"red": 2, "green": 1}  # BGR index of the laser channel (not the detectors')
LEAD_IN = 8  # frames at the start with the laser off
VISIBLE_RISE = 25  # grey levels the laser must add somewhere for the spot to be visible
REF = (1920.0, 1080.0)  # errors in screen px of a 1920x1080 screen
MOTION_SAMPLES = 8  # path samples over each row's exposure


def resolution_class(width: int, height: int) -> str:
    """``<640x480``, ``640x480-1280x720`` or ``>1280x720`` (pixel count)."""
    n = width * height
    return "<640x480" if n < 640 * 480 else ("640x480-1280x720" if n <= 1280 * 720 else ">1280x720")


@dataclass(frozen=True)
class LaserParams:
    """The laser and the content of a scene (units in each field's comment)."""

    colour: str  # "red" | "green"
    look: str  # one of LOOKS
    power: float  # the laser channel's peak on the screen, times the clipping level
    crosstalk: float  # the other channels' response to the laser, relative
    spot_px: float  # clipped diameter of a still spot, camera px
    sigma_px: float  # the beam's Gaussian sigma, screen px
    bloom: float  # glow amplitude relative to the peak
    bloom_px: float  # glow decay length, screen px
    slide_class: str  # one of SLIDE_CLASSES
    video: bool  # slides hold a video window
    fps: float
    frames: int
    tremor_px: float  # hand tremor amplitude, screen px (per 1920)
    speed: float  # mean move speed, screen px/s (per 1920)
    seed: int

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(math.log(lo), math.log(hi))))


def screen_per_camera_px(scene: ScreenScene, uv: FloatArray) -> FloatArray:
    """Screen px (of the scene's screen) per camera px at image points ``uv`` (N, 2):
    the square root of the local area scale."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    d = 0.5
    a = scene.image_to_screen(uv + np.array([d, 0.0])) - scene.image_to_screen(
        uv - np.array([d, 0.0])
    )
    b = scene.image_to_screen(uv + np.array([0.0, d])) - scene.image_to_screen(
        uv - np.array([0.0, d])
    )
    out: FloatArray = np.sqrt(np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))
    return out


def ref_scale(scene: ScreenScene) -> FloatArray:
    """Factors (2,) taking the scene's screen px to those of a 1920x1080 screen."""
    return np.array([REF[0] / scene.screen_px[0], REF[1] / scene.screen_px[1]])


def tolerance_px(scene: ScreenScene, uv: FloatArray) -> FloatArray:
    """Issue 12's tolerance at image points ``uv`` (N, 2), screen px of a 1920x1080
    screen: 1.5, or the length of 0.5 camera px where that is larger."""
    s = float(np.sqrt(np.prod(ref_scale(scene))))
    out: FloatArray = np.maximum(1.5, 0.5 * s * screen_per_camera_px(scene, uv))
    return out


def draw_laser(seed: int, scene: ScreenScene, *, frames: int = 75) -> LaserParams:
    """The laser and content of scene ``seed`` (see the module docstring for the ranges)."""
    rng = np.random.default_rng([seed, 1212])
    colour = COLOURS[int(rng.integers(2))]
    look = LOOKS[int(rng.integers(3))]
    power = _loguniform(rng, 2.0, 60.0)
    # the other channels' peak over clipping: white-core spots clip them too
    others = _loguniform(rng, 1.3, 8.0) if look == "white-core" else float(rng.uniform(0.12, 0.75))
    crosstalk = min(0.5, others / power)
    spot_px = _loguniform(rng, 2.0, 20.0)
    centre = scene.screen_to_image(np.array([[scene.screen_px[0] / 2, scene.screen_px[1] / 2]]))
    scale = float(screen_per_camera_px(scene, centre)[0])
    sigma = spot_px * scale / (2.0 * math.sqrt(2.0 * math.log(power)))
    bloom = _loguniform(rng, 0.03, 0.2) / power if look == "bloom" else 0.0
    return LaserParams(
        colour=colour,
        look=look,
        power=power,
        crosstalk=crosstalk,
        spot_px=spot_px,
        sigma_px=sigma,
        bloom=bloom,
        bloom_px=sigma * float(rng.uniform(2.5, 6.0)),
        slide_class=SLIDE_CLASSES[int(rng.integers(3))],
        video=bool(rng.random() < 0.5),
        fps=30.0,
        frames=frames,
        tremor_px=_loguniform(rng, 0.3, 3.0),
        speed=_loguniform(rng, 150.0, 1500.0),
        seed=seed,
    )


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

    def __init__(self, params: LaserParams, screen_px: tuple[int, int]) -> None:
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
    # visible in the frame as delivered (after the codec), judged like ``visible`` on the
    # frame against the same frame rendered and encoded without the laser
    delivered: bool = False

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


# ------------------------------------------------------------------- rendering


class LaserScene:
    """A drawn laser scene: :meth:`frames` yields (BGR image, truth) for every frame.

    ``scene``: the camera watching the screen (:mod:`omnidev.sim.screen_scenes`);
    ``laser``: the laser and content (:class:`LaserParams`).
    """

    def __init__(self, seed: int, *, frames: int = 75) -> None:
        self.seed = seed
        self.scene = draw_scene(seed)
        self.laser = draw_laser(seed, self.scene, frames=frames)
        self.path = LaserPath(self.laser, self.scene.screen_px)
        rng = np.random.default_rng([seed, 3131])
        changes, t = [], 0.0
        duration = frames / self.laser.fps
        while t < duration:
            changes.append(t)
            t += float(rng.uniform(1.0, 4.0))
        self._changes = np.array(changes)
        self._slide_seeds = [int(x) for x in rng.integers(0, 2**31, len(changes))]
        self._slides: dict[int, LaserSlide] = {}  # for moving_boxes

    def classes(self) -> dict[str, str]:
        """The scene's class in each reported axis (issue 12's five, and more)."""
        W, H = self.scene.size
        sc = self.scene.classes()
        return {
            "look": self.laser.look,
            "colour": self.laser.colour,
            "compression": self.scene.compression.codec,
            "slide": self.laser.slide_class,
            "resolution": resolution_class(W, H),
            "size": "2-5px"
            if self.laser.spot_px < 5
            else ("5-10px" if self.laser.spot_px < 10 else "10-20px"),
            "video": "yes" if self.laser.video else "no",
            "angle": sc["angle"],
            "exposure": sc["exposure"],
        }

    def slide_at(self, t: float) -> int:
        return int(np.searchsorted(self._changes, t, side="right")) - 1

    def moving_boxes(self, i: int) -> list[tuple[int, int, int, int]]:
        """Screen boxes (x0, y0, x1, y1), screen px, exclusive ends, where the content
        shown on frame ``i`` moves from frame to frame: the video window (discs of the
        laser's colour among others move in it) and the drifting blob."""
        t = i / self.laser.fps
        which = self.slide_at(t)
        slide = self._slides.get(which)
        if slide is None:
            p = self.laser
            SW, SH = self.scene.screen_px
            slide = LaserSlide(p.slide_class, SW, SH, p.colour, self._slide_seeds[which], p.video)
            self._slides = {which: slide}  # frames ask in order: keep the last slide only
        return slide.changed_boxes(t)

    def _row_mid(self, v: float) -> float:
        """Offset (s) of the middle of row ``v``'s exposure from the frame's time."""
        return float(self.scene.row_time(v)) + 0.5 * self.scene.exposure_s

    def truth(self, i: int, change: bool) -> LaserTruth:
        """The truth of frame ``i`` (``visible`` still to be judged on the render)."""
        t = i / self.laser.fps
        sc = self.scene
        if not self.path.on(i):
            return LaserTruth(i, False, None, None, False, 1.5, 0.0, change)
        k = 16
        offs = (np.arange(k) + 0.5) / k - 0.5
        xy = self.path.position(np.array([t]))[0]
        tr = t
        for _ in range(2):  # the row the spot lies on sets its exposure time
            uv = sc.screen_to_image(xy[None])[0]
            if not np.all(np.isfinite(uv)):
                return LaserTruth(i, True, None, None, False, 1.5, 0.0, change)
            tr = t + self._row_mid(float(uv[1]))
            xy = self.path.position(tr + offs * sc.exposure_s).mean(axis=0)
        uv = sc.screen_to_image(xy[None])[0]
        v1 = self.path.position(np.array([tr - 0.005, tr + 0.005]))
        speed = float(np.hypot(*(v1[1] - v1[0]))) / 0.01 * REF[0] / sc.screen_px[0]
        tol = float(tolerance_px(sc, uv[None])[0])
        ok = bool(np.all(np.isfinite(uv)) and sc.visible(xy[None])[0])
        return LaserTruth(
            i, True, (float(xy[0]), float(xy[1])), (float(uv[0]), float(uv[1])), ok, tol, speed,
            change,
        )  # fmt: skip

    def _light(self, xy: FloatArray, t: FloatArray) -> FloatArray:
        """The laser's light (N, 3) BGR at screen points ``xy`` (N, 2) at times ``t`` (N,)."""
        p = self.laser
        times, inv = np.unique(np.round(np.asarray(t, float), 6), return_inverse=True)
        centres = self.path.position(times)[inv.reshape(-1)]
        d2 = ((xy - centres) ** 2).sum(axis=1)
        level = np.exp(-d2 / (2.0 * p.sigma_px**2))
        if p.bloom > 0:
            level += p.bloom * np.exp(-np.sqrt(d2) / p.bloom_px)
        level *= p.power * self.path.power(float(times.mean())) / self.scene.white_level
        weights = np.full(3, p.crosstalk)
        weights[_LASER_CH[p.colour]] = 1.0
        out: FloatArray = level[:, None] * weights[None, :]
        return out

    def _bbox(self, t: float) -> tuple[float, float, float, float]:
        p, sc = self.laser, self.scene
        span = self.path.position(t + np.linspace(0.0, 1.0, 9) * (sc.exposure_s + sc.readout_s))
        reach = 3.5 * p.sigma_px + (8.0 * p.bloom_px if p.bloom > 0 else 0.0) + 2.0
        lo, hi = span.min(axis=0) - reach, span.max(axis=0) + reach
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    def frames(self) -> Iterator[tuple[NDArray[np.uint8], LaserTruth]]:
        """The camera's frames as the detector gets them (auto-exposure, the scene's
        codec), each with its truth.

        ``delivered`` is judged on a twin stream: every frame also sensed without the
        laser (same exposure, same noise) and encoded on its own; a spot the codec
        smoothed or quantized away raises the laser channel by less than
        :data:`VISIBLE_RISE` there."""
        sc, p = self.scene, self.laser
        r = renderer_for(sc)
        SW, SH = sc.screen_px
        truths: list[LaserTruth] = []
        twins: list[NDArray[np.uint8]] = []  # the frames sensed without the laser
        bare: list[NDArray[np.float32] | None] = [None]  # this frame's radiance without it
        rad = max(1.5, 0.5 * p.spot_px)  # visibility is judged within this of the centre
        c = _LASER_CH[p.colour]
        gain = r.base_exposure * sc.colour_gain[c]
        lut = 255.0 * np.linspace(0.0, 1.0, 4096) ** (1.0 / sc.camera_gamma)

        def to8(L: NDArray[np.float32]) -> NDArray[np.float64]:
            out: NDArray[np.float64] = lut[np.clip(L * gain * 4095.0, 0, 4095).astype(np.int32)]
            return out

        def radiances() -> Iterator[tuple[NDArray[np.float32], float]]:
            slide: LaserSlide | None = None
            last = -1
            for i in range(p.frames):
                t = i / p.fps
                which = self.slide_at(t)
                if which != last:
                    slide = LaserSlide(
                        p.slide_class, SW, SH, p.colour, self._slide_seeds[which], p.video
                    )
                assert slide is not None
                truth = self.truth(i, which != last and i > 0)
                last = which
                L = r.radiance(slide.frame(t), t)
                bare[0] = None
                if truth.on:
                    box = self._bbox(t)
                    r0, r1, c0, c1 = r._window(box)
                    bare[0] = L.copy()
                    before = to8(L[r0:r1, c0:c1, c].copy())
                    r._add_extra(L, t, None, self._light, box, MOTION_SAMPLES)
                    rise = to8(L[r0:r1, c0:c1, c]) - before
                    visible = False
                    if truth.visible and truth.uv is not None and rise.size:
                        # judged within the still spot's clipped radius of its centre
                        yy, xx = np.mgrid[r0:r1, c0:c1]
                        near = (xx - truth.uv[0]) ** 2 + (yy - truth.uv[1]) ** 2 <= rad * rad
                        visible = bool(near.any() and float(rise[near].max()) >= VISIBLE_RISE)
                    if not visible:
                        truth = _replace_truth(truth, visible=False)
                truths.append(truth)
                yield L, t

        def sense_twin(seed: int, exposure: float, image: NDArray[np.uint8]) -> None:
            twins.append(image if bare[0] is None else r.sensor(bare[0], exposure, seed))

        images, _, _ = _expose(sc, r, radiances(), 0, sense_twin)
        out = compress_frames(images, sc.compression, fps=p.fps)
        del images
        without = compress_frames(twins, sc.compression, fps=p.fps)
        twins.clear()
        for i, truth in enumerate(truths):
            if truth.visible and truth.uv is not None:
                rise = _rise_near(out[i], without[i], c, truth.uv, rad)
                truths[i] = _replace_truth(truth, delivered=rise >= VISIBLE_RISE)
        del without
        yield from zip(out, truths, strict=True)


def _rise_near(
    img: NDArray[np.uint8],
    bare: NDArray[np.uint8],
    c: int,
    uv: tuple[float, float],
    rad: float,
) -> float:
    """The largest rise of channel ``c`` of ``img`` over ``bare`` within ``rad`` px of
    ``uv`` (image px), in grey levels (0 where no pixel is that near)."""
    h, w = img.shape[:2]
    u0, u1 = max(0, math.floor(uv[0] - rad)), min(w, math.ceil(uv[0] + rad) + 1)
    v0, v1 = max(0, math.floor(uv[1] - rad)), min(h, math.ceil(uv[1] + rad) + 1)
    if u0 >= u1 or v0 >= v1:
        return 0.0
    yy, xx = np.mgrid[v0:v1, u0:u1]
    near = (xx - uv[0]) ** 2 + (yy - uv[1]) ** 2 <= rad * rad
    if not near.any():
        return 0.0
    d = img[v0:v1, u0:u1, c].astype(np.int16) - bare[v0:v1, u0:u1, c]
    return float(d[near].max())


def _replace_truth(t: LaserTruth, **kw: Any) -> LaserTruth:
    d = asdict(t)
    d.update(kw)
    return LaserTruth(**d)


def screen_mask(scene: ScreenScene, grow_px: int = 3) -> NDArray[np.bool_]:
    """H x W: the lit screen area in the image, grown by ``grow_px`` (as a calibration's
    screen region)."""
    W, H = scene.size
    mask = np.zeros((H, W), np.uint8)
    border = scene.screen_to_image(scene.screen_border(200))
    border = border[np.all(np.isfinite(border), axis=1)]
    cv2.fillPoly(mask, [np.round(border).astype(np.int32)], 1)
    k = 2 * grow_px + 1
    out: NDArray[np.bool_] = cv2.dilate(mask, np.ones((k, k), np.uint8)).astype(bool)
    return out
