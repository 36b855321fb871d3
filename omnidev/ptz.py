"""Virtual pan-tilt-zoom: steer a perspective view smoothly, at a bounded angular rate.

:class:`ViewController` is the small public steering API (the daemon's ``omnidev ctl
view`` and, later, auto-framing drive it): :meth:`~ViewController.set_target` takes
an absolute pose (pan, tilt, fov in degrees; any of them may be left as it is),
:meth:`~ViewController.move` a relative one, and :meth:`~ViewController.step`
advances the current pose towards the target by at most ``max_deg_s * dt`` degrees
(the pose moves along a straight line in (pan, tilt, fov), so every axis arrives
at once; pan goes the short way round). Pure arithmetic, thread-safe: one thread
may set targets while another steps.

:func:`parse_moves` reads the ``pan=... tilt=... fov=...`` words of ``omnidev ctl
view``: a plain number is absolute (``pan=30``), a signed one relative (``pan=+10``,
``fov=-10``), and ``pan==-30`` is the absolute -30.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

from omnidev.errors import OmnidevError

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
