"""Omni videos of a room with a moving person-sized object, with truth (issue 16, auto-framing).

:func:`draw_video` draws one video from a seed: camera kind (equidistant fisheye looking
up, mounted low, or hyperbolic-mirror SVP camera), resolution, frame rate, a textured
:class:`~omnidev.sim.scene.RoomScene`, and a textured vertical cylinder (a person: 0.35-0.5 m
wide, 1.2-1.8 m tall) standing on the floor and walking around the camera along a random
path: segments of walking at 0.3-1.3 m/s (either way round, so it reverses), stops, a
slowly changing distance, starting near azimuth 0 so it crosses the panorama's seam.
Distractors: a flickering patch on a wall, a small second object (0.2 m) sliding along the
floor, a slow global lighting change, sensor noise. Kind ``empty`` has no object (and no
small object): a framer must give no target on it.

The object is absent for the first ``warmup_s`` (the camera sees the empty room, then the
person steps in). Truth per frame (:meth:`VideoRenderer.truth`): the direction (azimuth,
elevation, degrees, camera frame of docs/conventions.md) of the centre of the object's
visible part (the point on its axis halfway between the lowest and highest heights the
camera sees of it), or None while it is absent.

:class:`VideoRenderer` renders the static room once (area-averaged) and composites the
object, the distractors, lighting and noise per frame by ray casting each pixel's direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from omnidev.sim.fisheye import EquidistantFisheyeCamera
from omnidev.sim.mirrors import SvpHyperbolicCamera
from omnidev.sim.render import render_omni
from omnidev.sim.scene import RoomScene

FloatArray = NDArray[np.float64]
KINDS = ("normal", "empty")


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder on the floor: axis at (x, y), radius, height above the floor."""

    radius: float
    height: float
    colours: tuple[tuple[float, float, float], ...]  # BGR bands, bottom to top
    stripes: float  # stripes around it (count) for texture


@dataclass(frozen=True)
class Path2D:
    """Polar path around the camera: azimuth (deg, unwrapped) and distance (m) per frame."""

    azimuth_deg: FloatArray
    distance: FloatArray


@dataclass(frozen=True)
class AutoframeVideo:
    """One randomized video (see the module docstring)."""

    seed: int
    kind: str
    camera_kind: str  # "fisheye" or "hyperbolic"
    size: int
    fps: float
    frames: int
    warmup_frames: int
    floor_depth: float
    room: tuple[tuple[float, float], tuple[float, float]]
    person: Cylinder | None
    path: Path2D | None
    small: Cylinder | None
    small_path: Path2D | None
    flicker: tuple[int, float, float, float, float] | None  # face, s0, t0, size, depth
    light: tuple[float, float, float]  # amplitude, period s, phase
    noise_sigma: float
    extra: dict[str, Any] = field(default_factory=dict)

    def camera(self) -> EquidistantFisheyeCamera | SvpHyperbolicCamera:
        if self.camera_kind == "fisheye":
            max_angle = math.radians(112.0)
            f = 0.48 * self.size / max_angle
            c = self.size / 2 - 0.5
            return EquidistantFisheyeCamera(
                f, (self.size, self.size), (c + 1.3, c - 2.2), max_angle
            )
        return SvpHyperbolicCamera.default(self.size)

    def describe(self) -> dict[str, Any]:
        """JSON-ready summary of what was drawn."""
        d: dict[str, Any] = {
            "seed": self.seed,
            "kind": self.kind,
            "camera": self.camera_kind,
            "size": self.size,
            "fps": self.fps,
            "frames": self.frames,
            "noise_sigma": round(self.noise_sigma, 2),
            "light_amplitude": round(self.light[0], 3),
            "flicker": self.flicker is not None,
            "small_object": self.small is not None,
        }
        if self.path is not None:
            az = self.path.azimuth_deg
            d["azimuth_range_deg"] = [round(float(az.min()), 1), round(float(az.max()), 1)]
        return d


def _walk(
    rng: np.random.Generator,
    n: int,
    fps: float,
    start_az: float,
    dist_range: tuple[float, float],
    speed_range: tuple[float, float],
    stops: bool,
) -> Path2D:
    """A random polar walk: segments of constant speed (m/s along the circle) or stops."""
    az = np.empty(n)
    dist = np.empty(n)
    a, d = start_az, float(rng.uniform(*dist_range))
    direction = float(rng.choice([-1.0, 1.0]))
    d_target = float(rng.uniform(*dist_range))
    i = 0
    while i < n:
        seg = max(1, round(rng.uniform(0.8, 2.5) * fps))
        stop = stops and rng.random() < 0.2
        if rng.random() < 0.4:
            direction = -direction
        speed = 0.0 if stop else float(rng.uniform(*speed_range))
        for _ in range(seg):
            if i >= n:
                break
            a += direction * math.degrees(speed / fps / d)
            d += float(np.clip(d_target - d, -0.15 / fps, 0.15 / fps))
            if abs(d_target - d) < 0.01:
                d_target = float(rng.uniform(*dist_range))
            az[i], dist[i] = a, d
            i += 1
    return Path2D(az, dist)


def _colour(rng: np.random.Generator) -> tuple[float, float, float]:
    b, g, r = (float(c) for c in rng.uniform(20, 235, 3))
    return b, g, r


def draw_video(
    seed: int, *, kind: str | None = None, seconds: float = 8.0, camera: str | None = None
) -> AutoframeVideo:
    """Video ``seed`` (kind drawn: 1 in 8 ``empty`` unless given)."""
    rng = np.random.default_rng([seed, 16004])
    kind = kind or ("empty" if rng.random() < 0.125 else "normal")
    if kind not in KINDS:
        raise ValueError(f"unknown video kind {kind!r} ({', '.join(KINDS)})")
    camera_kind = camera or str(rng.choice(["fisheye", "hyperbolic"]))
    size = int(rng.choice([400, 480, 560, 640]))
    fps = float(rng.choice([10.0, 12.5, 15.0]))
    frames = round(seconds * fps)
    warmup = round(float(rng.uniform(0.8, 1.5)) * fps)
    if camera_kind == "fisheye":
        floor_depth = float(rng.uniform(0.25, 0.5))
    else:
        floor_depth = float(rng.uniform(1.0, 1.4))
    room = (
        (-float(rng.uniform(2.6, 3.2)), float(rng.uniform(2.6, 3.2))),
        (-float(rng.uniform(2.6, 3.2)), float(rng.uniform(2.6, 3.2))),
    )
    person = path = small = small_path = None
    n_move = frames - warmup
    if kind == "normal":
        cols = tuple(_colour(rng) for _ in range(3))
        person = Cylinder(
            float(rng.uniform(0.17, 0.25)),
            float(rng.uniform(1.2, 1.8)),
            cols,
            float(rng.integers(3, 9)),
        )
        path = _walk(rng, n_move, fps, float(rng.uniform(-50, 50)), (1.3, 2.1), (0.3, 1.3), True)
        if rng.random() < 0.5:
            small = Cylinder(0.1, 0.2, (_colour(rng),), 2.0)
            small_path = _walk(
                rng, frames, fps, float(rng.uniform(0, 360)), (1.2, 1.6), (0.1, 0.4), False
            )
    flicker = None
    if rng.random() < 0.6:
        flicker = (
            int(rng.integers(0, 4)),
            float(rng.uniform(-1.5, 1.0)),
            float(rng.uniform(-0.1, 0.6)),
            float(rng.uniform(0.2, 0.4)),
            float(rng.uniform(0.2, 0.5)),
        )
    light = (
        float(rng.uniform(0.0, 0.12)),
        float(rng.uniform(3.0, 10.0)),
        float(rng.uniform(0, 6.3)),
    )
    return AutoframeVideo(
        seed, kind, camera_kind, size, fps, frames, warmup, floor_depth, room, person, path,
        small, small_path, flicker, light, float(rng.uniform(1.0, 5.0)),
    )  # fmt: skip


def _hit_cylinder(
    dirs: FloatArray, cx: float, cy: float, radius: float, z0: float, z1: float
) -> tuple[NDArray[np.bool_], FloatArray, FloatArray]:
    """Rays from the origin hitting a vertical cylinder's side or top: mask, angle, height."""
    dx, dy, dz = dirs[:, 0], dirs[:, 1], dirs[:, 2]
    a = dx * dx + dy * dy
    b = dx * cx + dy * cy
    c = cx * cx + cy * cy - radius * radius
    disc = b * b - a * c
    hit = disc > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (b - np.sqrt(np.where(hit, disc, 0))) / a
        z = t * dz
        side = hit & (t > 0) & (z >= z0) & (z <= z1)
        # the top, seen from above when it is below the viewpoint
        tc = z1 / dz
        px, py = tc * dx - cx, tc * dy - cy
        top = (z1 < 0) & (dz < 0) & (px * px + py * py <= radius * radius) & ~side
    ang = np.arctan2(np.where(side, t * dy - cy, py), np.where(side, t * dx - cx, px))
    height = np.where(side, z - z0, z1 - z0)
    return side | top, ang, height


class VideoRenderer:
    """Renders the frames of one :class:`AutoframeVideo` (BGR uint8 omni images)."""

    def __init__(self, video: AutoframeVideo) -> None:
        self.video = video
        cam = video.camera()
        self.camera = cam
        (x0, x1), (y0, y1) = video.room
        self.scene = RoomScene(
            seed=video.seed, x_range=(x0, x1), y_range=(y0, y1), floor_depth=video.floor_depth
        )
        self.background = render_omni(cam, self.scene, supersample=2).astype(np.float64)
        w, h = cam.image_size
        vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
        uv = np.stack([uu, vv], -1).reshape(-1, 2)
        dirs = cam.back_project(uv)
        _, ok = cam.project(dirs, finite=False)
        self.index = np.flatnonzero(ok)
        d = dirs[ok]
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        az = np.arctan2(d[:, 1], d[:, 0])
        order = np.argsort(az)
        self.index, self.dirs, self.azimuths = self.index[order], d[order], az[order]
        self.flat = self.background.reshape(-1, 3).astype(np.float32)
        fm = self._flicker_mask()
        self.flicker_index = None if fm is None else self.index[fm > 0]

    def _flicker_mask(self) -> FloatArray | None:
        fl = self.video.flicker
        if fl is None:
            return None
        face, s0, t0, size, _ = fl
        dist, fidx = self.scene.intersect(np.zeros_like(self.dirs), self.dirs)
        p = dist[:, None] * self.dirs
        s = np.where(fidx < 2, p[:, 1], p[:, 0])
        t = p[:, 2]
        m = (fidx == face) & (s >= s0) & (s <= s0 + size) & (t >= t0) & (t <= t0 + size)
        return np.asarray(m, np.float64)

    def _position(self, path: Path2D, j: int) -> tuple[float, float]:
        a = math.radians(path.azimuth_deg[j])
        d = path.distance[j]
        return d * math.cos(a), d * math.sin(a)

    def _paint(self, out: NDArray[np.float32], obj: Cylinder, path: Path2D, j: int) -> None:
        cx, cy = self._position(path, j)
        z0 = -self.video.floor_depth
        # only the rays within the object's azimuth range (rays are sorted by azimuth)
        a = math.atan2(cy, cx)
        half = math.asin(min(1.0, obj.radius / math.hypot(cx, cy))) + 0.02
        rows = []
        for lo, hi in ((a - half, a + half), (a - half + 2 * math.pi, a + half + 2 * math.pi),
                       (a - half - 2 * math.pi, a + half - 2 * math.pi)):  # fmt: skip
            i0, i1 = np.searchsorted(self.azimuths, [lo, hi])
            if i1 > i0:
                rows.append(np.arange(i0, i1))
        if not rows:
            return
        sel = np.concatenate(rows)
        m, ang, height = _hit_cylinder(self.dirs[sel], cx, cy, obj.radius, z0, z0 + obj.height)
        if not np.any(m):
            return
        hit = self.index[sel][m]
        band = np.clip(
            (height[m] / obj.height * len(obj.colours)).astype(int), 0, len(obj.colours) - 1
        )
        col = np.asarray(obj.colours)[band]
        shade = 0.75 + 0.25 * np.cos(ang[m] - math.atan2(-cy, -cx))  # lit from the camera side
        stripe = 1.0 + 0.15 * np.sin(obj.stripes * ang[m])
        out[hit] = col * (shade * stripe)[:, None]

    def render(self, i: int) -> NDArray[np.uint8]:
        """Frame ``i``."""
        v = self.video
        t = i / v.fps
        flat = self.flat.copy()
        if self.flicker_index is not None and v.flicker is not None:
            r = np.random.default_rng([v.seed, 7, i])
            if r.random() < 0.3:
                flat[self.flicker_index] *= np.float32(1.0 - v.flicker[4])
        if v.small is not None and v.small_path is not None:
            self._paint(flat, v.small, v.small_path, i)
        j = i - v.warmup_frames
        if v.person is not None and v.path is not None and j >= 0:
            self._paint(flat, v.person, v.path, j)
        amp, period, phase = v.light
        gain = 1.0 + amp * math.sin(2 * math.pi * t / period + phase)
        noise = np.random.default_rng([v.seed, 11, i]).standard_normal(flat.shape, np.float32)
        img = flat * np.float32(gain) + np.float32(v.noise_sigma) * noise + np.float32(0.5)
        return np.clip(img, 0, 255).astype(np.uint8).reshape(self.background.shape)

    def truth(self, i: int) -> tuple[float, float] | None:
        """(azimuth, elevation) degrees of the visible object's centre at frame ``i``."""
        v = self.video
        j = i - v.warmup_frames
        if v.person is None or v.path is None or j < 0:
            return None
        cx, cy = self._position(v.path, j)
        d = math.hypot(cx, cy)
        lo_el, hi_el = self.camera.default_elevation_deg()
        z0 = -v.floor_depth
        z1 = z0 + v.person.height
        # the near side of the cylinder bounds what is seen; heights at the axis distance
        zlo = max(z0, d * math.tan(math.radians(lo_el)))
        zhi = min(z1, d * math.tan(math.radians(hi_el)))
        zc = 0.5 * (zlo + zhi)
        return math.degrees(math.atan2(cy, cx)), math.degrees(math.atan2(zc, d))
