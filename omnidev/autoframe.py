"""Auto-framing: find the most salient moving object in a panorama and steer a view at it.

Pure image arithmetic (numpy / OpenCV in, numbers out, no device): :class:`AutoFramer`
takes panorama frames (an angular :class:`~omnidev.views.Panorama` of the camera, its
geometry in :class:`AutoFrameConfig`) and returns a :class:`Target`, the (pan, tilt) in
degrees that a perspective view (:class:`~omnidev.views.Perspective`, ``pan`` = azimuth
atan2(y, x), ``tilt`` = elevation, camera frame of docs/conventions.md) should point at,
or None when nothing is followed.

Per frame:

1. the panorama is resized to a working grid of ``deg_per_px`` degrees per pixel (so every
   parameter is in degrees, whatever the panorama's size) and scaled to a
   fixed mean brightness (a global lighting change is not motion);
2. a kept background subtractor (OpenCV's MOG2, or KNN: ``method``) marks foreground
   in colour (no shadow detection: a dark object in front of a lighter wall would be taken
   for a shadow); MOG2 learns at 1 / ``history`` from the first frame (OpenCV's default
   learns faster while its history fills, and absorbs an object that enters early), KNN at
   OpenCV's automatic rate; a morphological opening then closing cleans the mask;
3. connected blobs of at least ``min_area_deg2`` square degrees; blobs touching the left
   and the right edge of a full 360-degree panorama on the same rows are one blob (an
   object crossing the seam), its centroid computed across the seam;
4. blobs are matched to tracks (nearest, within ``gate_deg``, azimuth wrapping round);
   a track's azimuth is filtered (alpha-beta: position and rate), its elevation smoothed
   (``alpha_el``), and its salience is its
   mean area times its age (capped at ``persist_s``);
5. the followed track is kept while it is seen; another takes over only when its
   salience exceeds the followed one's by ``switch_ratio`` for ``switch_hold_s``; a
   followed track unseen for ``lost_s`` is dropped (until then the target holds, and a
   confirmed track within ``gate_deg`` of it re-acquires at once);
6. the output target moves only when the filtered position leaves a dead zone of
   ``dead_zone_deg`` in pan (``reverse_zone_deg`` when the move would turn the pan back,
   and for the first move after lock-on, whose direction against the view's acquiring
   swing is unknown here) or ``tilt_zone_deg`` in tilt (so a still or jittering object
   does not make it hunt).

:class:`Follower` is a small rate-limited steering loop (at most ``max_deg_s`` along a
straight line in (pan, tilt), pan the short way round) so the whole loop can be
evaluated; a view controller (the daemon's virtual PTZ) can take its place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.views import Panorama

METHODS = ("mog2", "knn")


def wrap_deg(a: float) -> float:
    """An angle in [-180, 180)."""
    return (a + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class AutoFrameConfig:
    """What :class:`AutoFramer` needs: the panorama's geometry and the tuning (degrees, s)."""

    panorama: Panorama
    method: str = "mog2"
    deg_per_px: float = 1.0
    history: int = 300
    fixed_rate: bool = True  # MOG2 learns at 1 / history from the first frame (not faster)
    var_threshold: float = 25.0
    min_area_deg2: float = 200.0
    max_foreground: float = 0.3  # share of the frame: above it the frame is skipped
    open_px: int = 3
    close_px: int = 5
    gate_deg: float = 15.0
    confirm_frames: int = 4
    persist_s: float = 2.0
    switch_ratio: float = 2.0
    switch_hold_s: float = 0.6
    lost_s: float = 2.0
    alpha: float = 0.5
    beta: float = 0.1
    alpha_el: float = 0.25  # elevation: smoothed harder, no rate (blobs' heights jitter)
    dead_zone_deg: float = 2.0
    reverse_zone_deg: float = 4.0
    tilt_zone_deg: float = 3.0

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"auto-framing method must be one of {', '.join(METHODS)}")
        if self.panorama.elevation_deg is None:
            raise ValueError("auto-framing needs the panorama's elevation_deg")
        if not self.deg_per_px > 0:
            raise ValueError("deg_per_px must be > 0")


@dataclass(frozen=True)
class Target:
    """Where to point a view: pan (azimuth) and tilt (elevation), degrees; the track
    followed, its mean area (square degrees) and whether it is seen in this frame."""

    pan_deg: float
    tilt_deg: float
    track: int
    area_deg2: float
    seen: bool


@dataclass(frozen=True)
class Blob:
    """A moving region: centroid azimuth / elevation (degrees) and area (square degrees)."""

    azimuth_deg: float
    elevation_deg: float
    area_deg2: float


@dataclass
class _Track:
    ident: int
    az: float
    el: float
    rate_az: float
    area: float
    first_t: float
    last_t: float
    hits: int = 1
    areas: list[float] = field(default_factory=list)

    def salience(self, persist_s: float) -> float:
        age = min(self.last_t - self.first_t, persist_s) + 1e-3
        return float(np.mean(self.areas[-30:])) * age


def seam_blobs(
    mask: NDArray[np.uint8], min_area_px: int, wrap: bool
) -> list[tuple[float, float, int]]:
    """Blobs of a binary mask as (centroid column, centroid row, area px), area >= min.

    With ``wrap``, a blob touching column 0 and one touching the last column on the same
    (or a neighbouring) row are one; its centroid column is then measured across the seam
    (it may be negative: add the width to bring it into the image).
    """
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    w = mask.shape[1]
    parent = list(range(n))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    right_side: set[int] = set()
    if wrap and n > 1:
        left, right = labels[:, 0], labels[:, -1]
        for shift in (-1, 0, 1):
            r = np.roll(right, shift)
            both = (left > 0) & (r > 0)
            for a, b in zip(left[both], r[both], strict=True):
                ra, rb = find(int(a)), find(int(b))
                if ra != rb:
                    parent[rb] = ra
                right_side.add(int(b))
    groups: dict[int, list[int]] = {}
    for k in range(1, n):
        groups.setdefault(find(k), []).append(k)
    out = []
    for members in groups.values():
        area = int(sum(stats[k, cv2.CC_STAT_AREA] for k in members))
        if area < min_area_px:
            continue
        merged = len(members) > 1 and any(k in right_side for k in members)
        sx = sy = 0.0
        for k in members:
            a = float(stats[k, cv2.CC_STAT_AREA])
            cx = float(cents[k][0])
            if merged and k in right_side:
                cx -= w
            sx += a * cx
            sy += a * float(cents[k][1])
        out.append((sx / area, sy / area, area))
    return out


class AutoFramer:
    """Auto-framing over panorama frames (see the module docstring)."""

    def __init__(self, config: AutoFrameConfig) -> None:
        self.config = config
        p = config.panorama
        assert p.elevation_deg is not None
        self.bottom, self.top = p.elevation_deg
        self.work_size = (
            max(8, round(p.azimuth_span_deg / config.deg_per_px)),
            max(8, round((self.top - self.bottom) / config.deg_per_px)),
        )
        self.wrap = abs(p.azimuth_span_deg - 360.0) < 1e-9
        if config.method == "mog2":
            self.subtractor: cv2.BackgroundSubtractor = cv2.createBackgroundSubtractorMOG2(
                config.history, config.var_threshold, False
            )
        else:
            self.subtractor = cv2.createBackgroundSubtractorKNN(
                config.history, 4.0 * config.var_threshold, False
            )
        self.kernel_open = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (config.open_px,) * 2)
        self.kernel_close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (config.close_px,) * 2)
        # KNN fills its sample buffer at the learning rate: it needs OpenCV's automatic one
        fixed = config.fixed_rate and config.method == "mog2"
        self.learning_rate = 1.0 / config.history if fixed else -1.0
        self.tracks: list[_Track] = []
        self.followed: _Track | None = None
        self.challenger: tuple[int, float] | None = None  # track id, since when
        self.output: tuple[float, float] | None = None
        self.direction = 0  # the sign of the output's last pan move
        self.last_t: float | None = None
        self._next_id = 1
        self.mask: NDArray[np.uint8] | None = None
        self.blobs_last: list[Blob] = []

    # geometry of the working grid
    def _azimuth(self, col: float) -> float:
        p = self.config.panorama
        frac = (col + 0.5) / self.work_size[0] * p.azimuth_span_deg
        return wrap_deg(p.azimuth_start_deg - frac if p.clockwise else p.azimuth_start_deg + frac)

    def _elevation(self, row: float) -> float:
        return self.top - (row + 0.5) / self.work_size[1] * (self.top - self.bottom)

    def blobs(self, frame: NDArray[np.uint8]) -> list[Blob] | None:
        """The moving blobs of one panorama frame (None: skipped, a global change)."""
        c = self.config
        img = cv2.resize(frame, self.work_size, interpolation=cv2.INTER_AREA)
        mean = float(img.mean())
        if mean > 1.0:
            img = cv2.convertScaleAbs(img, alpha=110.0 / mean)
        fg = self.subtractor.apply(img, learningRate=self.learning_rate)
        raw = (fg == 255).astype(np.uint8)
        opened = cv2.morphologyEx(raw, cv2.MORPH_OPEN, self.kernel_open)
        mask = np.asarray(cv2.morphologyEx(opened, cv2.MORPH_CLOSE, self.kernel_close), np.uint8)
        self.mask = mask
        if mask.mean() > c.max_foreground:
            return None
        px_area = c.deg_per_px**2
        found = seam_blobs(mask, max(1, math.ceil(c.min_area_deg2 / px_area)), self.wrap)
        self.blobs_last = [
            Blob(self._azimuth(x), self._elevation(y), a * px_area) for x, y, a in found
        ]
        return self.blobs_last

    def _associate(self, blobs: list[Blob], t: float, dt: float) -> None:
        c = self.config
        pairs = []
        for ti, tr in enumerate(self.tracks):
            pa = tr.az + tr.rate_az * dt
            pe = tr.el
            for bi, b in enumerate(blobs):
                d = math.hypot(wrap_deg(b.azimuth_deg - pa), b.elevation_deg - pe)
                if d <= c.gate_deg:
                    pairs.append((d, ti, bi))
        used_t: set[int] = set()
        used_b: set[int] = set()
        for _, ti, bi in sorted(pairs):
            if ti in used_t or bi in used_b:
                continue
            used_t.add(ti)
            used_b.add(bi)
            tr, b = self.tracks[ti], blobs[bi]
            pa = tr.az + tr.rate_az * dt
            pe = tr.el
            ra, re = wrap_deg(b.azimuth_deg - pa), b.elevation_deg - pe
            tr.az = wrap_deg(pa + c.alpha * ra)
            tr.el = pe + c.alpha_el * re
            if dt > 0:
                tr.rate_az += c.beta * ra / dt
            tr.last_t = t
            tr.hits += 1
            tr.areas.append(b.area_deg2)
        for bi, b in enumerate(blobs):
            if bi not in used_b:
                self.tracks.append(
                    _Track(self._next_id, b.azimuth_deg, b.elevation_deg, 0.0,
                           b.area_deg2, t, t, 1, [b.area_deg2])
                )  # fmt: skip
                self._next_id += 1
        # unseen tracks coast on their rate for a little, then stop; old ones are dropped
        for tr in self.tracks:
            if tr.last_t < t:
                tr.rate_az *= 0.5
        self.tracks = [tr for tr in self.tracks if t - tr.last_t <= c.lost_s]

    def update(self, frame: NDArray[np.uint8], t: float) -> Target | None:
        """Feed the panorama frame taken at ``t`` seconds; the target to point at, or None."""
        c = self.config
        dt = 0.0 if self.last_t is None else max(0.0, t - self.last_t)
        self.last_t = t
        blobs = self.blobs(frame)
        if blobs is not None:
            self._associate(blobs, t, dt)
        confirmed = [tr for tr in self.tracks if tr.hits >= c.confirm_frames and tr.last_t == t]
        f = self.followed
        if f is not None and f not in self.tracks:
            f = None  # lost for longer than lost_s
        if f is not None and f.last_t < t and confirmed:
            # re-acquire: a confirmed track near where the followed one was lost
            near = [
                tr
                for tr in confirmed
                if math.hypot(wrap_deg(tr.az - f.az), tr.el - f.el) <= c.gate_deg
            ]
            if near:
                f = max(near, key=lambda tr: tr.salience(c.persist_s))
        if f is None:
            self.challenger = None
            if confirmed:
                f = max(confirmed, key=lambda tr: tr.salience(c.persist_s))
        elif confirmed:
            best = max(confirmed, key=lambda tr: tr.salience(c.persist_s))
            if best is not f and best.salience(c.persist_s) > c.switch_ratio * f.salience(
                c.persist_s
            ):
                if self.challenger is None or self.challenger[0] != best.ident:
                    self.challenger = (best.ident, t)
                elif t - self.challenger[1] >= c.switch_hold_s:
                    f, self.challenger = best, None
            else:
                self.challenger = None
        self.followed = f
        if f is None:
            self.output = None
            self.direction = 0
            return None
        if self.output is None:
            self.output = (f.az, f.el)
        else:
            pan, tilt = self.output
            dp = wrap_deg(f.az - pan)
            zone = c.dead_zone_deg
            if dp * self.direction <= 0:
                # turning back needs a longer way; so does the first step after lock-on:
                # the view's acquiring move went one way or the other, unknown here
                zone = c.reverse_zone_deg
            # pan and tilt leave their zones each on its own (a tilt step must not
            # drag the pan along by less than its zone, possibly turning it back)
            if abs(dp) > zone:
                pan = f.az
                self.direction = 1 if dp > 0 else -1
            if abs(f.el - tilt) > c.tilt_zone_deg:
                tilt = f.el
            self.output = (pan, tilt)
        return Target(
            self.output[0], self.output[1], f.ident, float(np.mean(f.areas[-30:])), f.last_t == t
        )


class Follower:
    """A rate-limited view pose: each :meth:`step` moves (pan, tilt) towards the target by
    at most ``max_deg_s * dt`` degrees along a straight line (pan the short way round)."""

    def __init__(self, max_deg_s: float, pan_deg: float = 0.0, tilt_deg: float = 0.0) -> None:
        if not max_deg_s > 0:
            raise ValueError("max_deg_s must be > 0")
        self.max_deg_s = max_deg_s
        self.pan = wrap_deg(pan_deg)
        self.tilt = tilt_deg
        self.arrived = False  # whether the last step reached its target

    def step(self, target: Target | tuple[float, float] | None, dt: float) -> tuple[float, float]:
        """The pose after ``dt`` seconds of moving towards ``target`` (None: stay)."""
        if target is not None:
            tp, tt = (target.pan_deg, target.tilt_deg) if isinstance(target, Target) else target
            dp, dtl = wrap_deg(tp - self.pan), tt - self.tilt
            dist = math.hypot(dp, dtl)
            room = self.max_deg_s * max(0.0, dt)
            k = 1.0 if dist <= room else room / dist
            self.arrived = dist <= room
            self.pan = wrap_deg(self.pan + k * dp)
            self.tilt += k * dtl
        return self.pan, self.tilt


def view_offset(
    pan_deg: float, tilt_deg: float, fov_deg: float, azimuth_deg: float, elevation_deg: float
) -> float:
    """Distance of a direction's image from a perspective view's centre, in view widths
    (inf when it is behind the view)."""
    from omnidev.views import view_rotation

    rot = view_rotation(pan_deg, tilt_deg, 0.0)
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    d = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    x, y, z = rot.T @ d
    if z <= 0:
        return math.inf
    return float(math.hypot(x / z, y / z) / (2 * math.tan(math.radians(fov_deg) / 2)))


def count_reversals(angles_deg: NDArray[np.float64] | list[float], min_swing_deg: float) -> int:
    """Reversals of direction of an (unwrapped) angle sequence, counting a turn only when the
    angle has moved ``min_swing_deg`` back from its last extreme (hysteresis)."""
    a = np.asarray(angles_deg, np.float64)
    if a.size < 2:
        return 0
    n = 0
    direction = 0
    extreme = a[0]
    for v in a[1:]:
        if direction == 0:
            if abs(v - extreme) >= min_swing_deg:
                direction = 1 if v > extreme else -1
                extreme = v
        elif direction > 0:
            if v > extreme:
                extreme = v
            elif extreme - v >= min_swing_deg:
                n += 1
                direction, extreme = -1, v
        else:
            if v < extreme:
                extreme = v
            elif v - extreme >= min_swing_deg:
                n += 1
                direction, extreme = 1, v
    return n
