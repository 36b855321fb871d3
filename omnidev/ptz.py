"""Virtual pan-tilt-zoom: steer a perspective view smoothly, at a bounded angular rate.

:class:`ViewController` is the small public steering API (the daemon's ``omnidev ctl
view`` and, later, auto-framing drive it): :meth:`~ViewController.set_target` takes
an absolute pose (pan, tilt, fov in degrees; any of them may be left as it is),
:meth:`~ViewController.move` a relative one, and :meth:`~ViewController.step`
advances the current pose towards the target by at most ``max_deg_s * dt`` degrees
(the pose moves along a straight line in (pan, tilt, fov), so every axis arrives
at once; pan goes the short way round). Pure arithmetic, thread-safe: one thread
may set targets while another steps.

:func:`coarse_maps` builds a perspective view's maps from the camera at every
``step``-th pixel in each direction and interpolates the rest (bilinear in the
source-pixel coordinates, which are smooth across a pinhole view): ``step`` squared
times fewer rays through the camera model, for the poses a view passes through
while it moves (the daemon builds exact maps when the move ends). Pixels next to
the edge of what the camera sees are left invalid rather than interpolated across
it; bench/ptz.py reports the largest difference from the exact maps.

:func:`parse_moves` reads the ``pan=... tilt=... fov=...`` words of ``omnidev ctl
view``: a plain number is absolute (``pan=30``), a signed one relative (``pan=+10``,
``fov=-10``), and ``pan==-30`` is the absolute -30.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import cv2
import numpy as np

from omnidev.camera import INVALID, CameraModel, Maps, build_maps
from omnidev.errors import OmnidevError
from omnidev.views import Perspective

MIN_FOV_DEG = 1.0
MAX_FOV_DEG = 179.0
MAX_TILT_DEG = 90.0
AXES = ("pan", "tilt", "fov")


@dataclass(frozen=True)
class Pose:
    """A perspective view's direction and zoom: pan (azimuth), tilt (+ up), horizontal fov,
    all in degrees."""

    pan: float
    tilt: float
    fov: float


def _wrap(deg: float) -> float:
    """An angle in [-180, 180)."""
    return (deg + 180.0) % 360.0 - 180.0


def clamp_pose(pose: Pose) -> Pose:
    """Tilt within [-90, 90], fov within [1, 179] degrees, pan in [-180, 180)."""
    return Pose(
        _wrap(pose.pan),
        min(MAX_TILT_DEG, max(-MAX_TILT_DEG, pose.tilt)),
        min(MAX_FOV_DEG, max(MIN_FOV_DEG, pose.fov)),
    )


class ViewController:
    """The pose of one steerable view and where it is going.

    Args:
        pose: the starting pose (also the first target).
        max_deg_s: the largest angular rate of a transition, degrees per second along
            the straight line in (pan, tilt, fov); 0 jumps to each target at once.
    """

    def __init__(self, pose: Pose, max_deg_s: float = 90.0) -> None:
        if not (max_deg_s >= 0 and math.isfinite(max_deg_s)):
            raise ValueError(f"max_deg_s must be a finite number >= 0, got {max_deg_s}")
        self.max_deg_s = float(max_deg_s)
        self._pose = clamp_pose(pose)
        self._target = self._pose
        self._lock = threading.Lock()

    @property
    def pose(self) -> Pose:
        return self._pose

    @property
    def target(self) -> Pose:
        return self._target

    @property
    def settled(self) -> bool:
        """True when the pose has reached the target."""
        return self._pose == self._target

    def set_target(
        self, pan: float | None = None, tilt: float | None = None, fov: float | None = None
    ) -> Pose:
        """Aim at an absolute pose (None keeps that axis's current target); returns it."""
        with self._lock:
            t = self._target
            self._target = clamp_pose(
                Pose(
                    t.pan if pan is None else float(pan),
                    t.tilt if tilt is None else float(tilt),
                    t.fov if fov is None else float(fov),
                )
            )
            return self._target

    def move(self, pan: float = 0.0, tilt: float = 0.0, fov: float = 0.0) -> Pose:
        """Move the target by these many degrees; returns the new target."""
        t = self._target
        return self.set_target(t.pan + pan, t.tilt + tilt, t.fov + fov)

    def step(self, dt: float) -> Pose:
        """Advance the pose ``dt`` seconds towards the target; returns the new pose."""
        with self._lock:
            p, t = self._pose, self._target
            d = (_wrap(t.pan - p.pan), t.tilt - p.tilt, t.fov - p.fov)
            dist = math.sqrt(sum(x * x for x in d))
            limit = self.max_deg_s * max(0.0, dt)
            if self.max_deg_s == 0 or dist <= limit:
                self._pose = t
            else:
                k = limit / dist
                self._pose = clamp_pose(Pose(p.pan + k * d[0], p.tilt + k * d[1], p.fov + k * d[2]))
            return self._pose


def parse_moves(words: list[str] | dict[str, str]) -> tuple[dict[str, float], dict[str, float]]:
    """``["pan=30", "tilt=+5", "fov=-10"]`` -> (absolute, relative) degrees per axis.

    A value with a leading ``+`` or ``-`` is relative (``pan=+10``, ``fov=-10``: 10
    degrees narrower); a plain number is absolute; ``pan==-30`` is absolute -30.

    >>> parse_moves(["pan=30", "tilt=+5", "fov=-10"])
    ({'pan': 30.0}, {'tilt': 5.0, 'fov': -10.0})
    >>> parse_moves(["pan==-30"])
    ({'pan': -30.0}, {})
    """
    items = list(words.items()) if isinstance(words, dict) else []
    if not isinstance(words, dict):
        for w in words:
            key, eq, val = str(w).partition("=")
            if not eq:
                raise OmnidevError(f"{w!r}: give AXIS=VALUE with AXIS one of pan, tilt, fov")
            items.append((key, val))
    absolute: dict[str, float] = {}
    relative: dict[str, float] = {}
    for key, raw in items:
        key = key.strip()
        text = str(raw).strip()
        if key not in AXES:
            raise OmnidevError(f"{key}={raw}: unknown axis {key!r} (axes: pan, tilt, fov)")
        forced_abs = text.startswith("=")
        if forced_abs:
            text = text[1:]
        try:
            value = float(text)
        except ValueError:
            raise OmnidevError(f"{key}={raw}: not a number of degrees") from None
        if not math.isfinite(value):
            raise OmnidevError(f"{key}={raw}: not a finite number of degrees")
        if key in absolute or key in relative:
            raise OmnidevError(f"{key} given twice")
        if not forced_abs and text[:1] in "+-":
            relative[key] = value
        else:
            absolute[key] = value
    if not absolute and not relative:
        raise OmnidevError("give at least one of pan=, tilt=, fov=")
    return absolute, relative


def coarse_maps(camera: CameraModel, view: Perspective, step: int = 4) -> Maps:
    """``view``'s maps from rays at every ``step``-th pixel, bilinear in between (see above).

    ``step`` 1 is :func:`~omnidev.camera.build_maps` itself. The coarse grid has the
    same optical centre and a focal length ``step`` times shorter, so its pixel ``j``
    looks where the full view's pixel ``(j + 0.5) * step - 0.5`` (relative to the
    centre) does; a pixel whose four coarse neighbours are not all valid is invalid.
    """
    if step < 1:
        raise ValueError(f"step must be >= 1, got {step}")
    if step == 1:
        return build_maps(camera, view)
    w, h = view.width, view.height
    # one coarse pixel of margin on each side, so that the edges are interpolated, not
    # held; the grid covers (w + 2 step) x (h + 2 step) pixels of the full view's plane
    cw, ch = -(-w // step) + 2, -(-h // step) + 2
    fc = view.focal_px / step
    fov = math.degrees(2 * math.atan(cw / 2 / fc))
    if not fov < 180:
        return build_maps(camera, view)
    coarse = build_maps(
        camera, Perspective(cw, ch, fov, view.pan_deg, view.tilt_deg, view.roll_deg)
    )
    # cv2.resize maps full pixel x to coarse (x + 0.5) / step - 0.5: the centres line
    # up when the full grid is cw * step wide; the view is its middle w x h (whole
    # pixels off-centre by (cw * step - w) / 2, an integer when w is even or step odd)
    big_w, big_h = cw * step, ch * step
    x0, y0 = (big_w - w) / 2, (big_h - h) / 2
    if x0 != int(x0) or y0 != int(y0):
        return build_maps(camera, view)
    xs, ys = slice(int(x0), int(x0) + w), slice(int(y0), int(y0) + h)

    def up(a: np.ndarray) -> np.ndarray:
        big = cv2.resize(a, (big_w, big_h), interpolation=cv2.INTER_LINEAR)
        return np.ascontiguousarray(big[ys, xs], np.float32)

    ok = up(coarse.valid.astype(np.float32)) >= 1.0 - 1e-6
    map_x = up(coarse.map_x)
    map_y = up(coarse.map_y)
    map_x[~ok] = INVALID
    map_y[~ok] = INVALID
    return Maps(map_x, map_y, ok, coarse.source_size)
