"""Random hand-held camera trajectories for the camera-mouse world (:mod:`omnidev.sim.handheld`).

World frame (metres) as in :mod:`omnidev.sim.handcam`: the monitor's screen plane is
z = 0 with the lit area [0, W] x [0, H] (x right, y down), z into the screen; the
camera is at z < 0. A trajectory is a list of keyframes (time, aim point on the plane
z = 0, camera centre, roll) joined by minimum-jerk moves (a hand moves, then rests),
plus a slow sway of the aim and the camera and physiological tremor (8-12 Hz) of the
aim. :meth:`Trajectory.poses` evaluates it at any times, vectorized.

Segments drawn by :func:`draw_path`: dwell, move, fast sweep (motion blur up to the
drawn bound), excursion (the aim goes past the screen's edge or corner until 1, 2 or
3-4 landmarks have left the picture, and comes back), distance change, obliqueness
change (up to 45 degrees off the screen normal), roll change (up to 30 degrees).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

SEGMENTS = ("dwell", "move", "sweep", "excursion", "distance", "oblique", "roll")
SEGMENT_P = (0.18, 0.27, 0.13, 0.18, 0.09, 0.09, 0.06)


@dataclass(frozen=True)
class Trajectory:
    """Keyframes (K,) ``t``, aim (K, 2) on z = 0, camera centre (K, 3), roll (K,) deg;
    sway: (n, 4) rows (freq Hz, amp m, phase x, phase y) for the aim and ``cam_sway``
    the same for the camera centre (m); tremor (n, 4) rows (freq Hz, amp rad, phase x,
    phase y) turning the aim. ``segments``: (start s, kind) of each segment."""

    t: FloatArray
    aim: FloatArray
    cam: FloatArray
    roll: FloatArray
    sway: FloatArray
    cam_sway: FloatArray
    tremor: FloatArray
    segments: tuple[tuple[float, str], ...]

    def state(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Aim (N, 3), camera centre (N, 3) and roll (N,) deg at times ``t`` (N,) s."""
        t = np.asarray(t, np.float64).reshape(-1)
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        t0, t1 = self.t[k], self.t[k + 1]
        tau = np.clip((t - t0) / np.maximum(t1 - t0, 1e-9), 0.0, 1.0)
        s = (tau**3 * (10 - 15 * tau + 6 * tau * tau))[:, None]
        aim = self.aim[k] + (self.aim[k + 1] - self.aim[k]) * s
        cam = self.cam[k] + (self.cam[k + 1] - self.cam[k]) * s
        roll = self.roll[k] + (self.roll[k + 1] - self.roll[k]) * s[:, 0]
        for f, a, px, py in self.sway:
            w = 2 * math.pi * f * t
            aim = aim + a * np.stack([np.sin(w + px), np.sin(w + py)], 1)
        for f, a, px, py in self.cam_sway:
            w = 2 * math.pi * f * t
            cam = cam + a * np.stack([np.sin(w + px), np.sin(w + py), 0.5 * np.sin(w + px + py)], 1)
        dist = np.linalg.norm(np.column_stack([aim, np.zeros(len(t))]) - cam, axis=1)
        for f, a, px, py in self.tremor:
            w = 2 * math.pi * f * t
            aim = aim + (dist * math.tan(a))[:, None] * np.stack(
                [np.sin(w + px), np.sin(w + py)], 1
            )
        return np.column_stack([aim, np.zeros(len(t))]), cam, roll

    def poses(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Camera centres (N, 3) and world-to-camera rotations (N, 3, 3) at times ``t``."""
        aim, cam, roll = self.state(t)
        return cam, look_at_many(cam, aim, roll)


def look_at_many(C: FloatArray, target: FloatArray, roll_deg: FloatArray) -> FloatArray:
    """Rotations (N, 3, 3) as :func:`omnidev.sim.handcam.look_at`, vectorized."""
    f = target - C
    f = f / np.linalg.norm(f, axis=1, keepdims=True)
    x = np.cross(np.array([0.0, 1.0, 0.0]), f)
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(f, x)
    R0 = np.stack([x, y, f], axis=1)
    a = np.radians(roll_deg)
    c, s = np.cos(a), np.sin(a)
    Rz = np.zeros((len(a), 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, s, -s, c, 1.0
    out: FloatArray = Rz @ R0
    return out


def camera_at(centre: FloatArray, dist: float, theta_deg: float, phi_deg: float) -> FloatArray:
    """Camera centre ``dist`` m from ``centre`` (3,), ``theta_deg`` off the screen normal,
    the tilt towards azimuth ``phi_deg`` (0 = +x)."""
    th, ph = math.radians(theta_deg), math.radians(phi_deg)
    out: FloatArray = centre + dist * np.array(
        [math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), -math.cos(th)]
    )
    return out


CountOut = Callable[[FloatArray, FloatArray, float], int]
"""(aim (3,), camera centre (3,), roll deg) -> landmarks out of the picture."""


def draw_path(
    rng: np.random.Generator,
    *,
    duration_s: float,
    screen_m: tuple[float, float],
    dist_m: float,
    dist_range_m: tuple[float, float],
    focal_px: float,
    exposure_s: float,
    max_blur_px: float,
    count_out: CountOut | None,
) -> Trajectory:
    """A random trajectory over ``duration_s`` seconds (see the module docstring).

    ``dist_m``: the starting distance from the screen centre; distance changes stay in
    ``dist_range_m``. Sweeps are timed so that the peak image motion over the exposure
    ``exposure_s`` is 0.3-1.0 x ``max_blur_px`` (``focal_px`` converts angles to px).
    ``count_out`` (None for scenes without landmarks) aims the excursions.
    """
    W, H = screen_m
    centre = np.array([W / 2, H / 2, 0.0])
    theta = float(abs(rng.normal(0, 10))) if rng.random() < 0.7 else float(rng.uniform(0, 35))
    phi = float(rng.uniform(0, 360))
    dist = dist_m
    cam = camera_at(centre, dist, min(theta, 45.0), phi)
    roll = float(np.clip(rng.normal(0, 4), -30, 30))
    aim = np.array([W * rng.uniform(0.3, 0.7), H * rng.uniform(0.3, 0.7)])
    ts, aims, cams, rolls = [0.0], [aim], [cam], [roll]
    segments: list[tuple[float, str]] = [(0.0, "dwell")]
    t = float(rng.uniform(0.3, 1.0))  # everything visible and still for a start
    ts.append(t)
    aims.append(aim)
    cams.append(cam)
    rolls.append(roll)

    def on_screen() -> FloatArray:
        return np.array([W * rng.uniform(0.03, 0.97), H * rng.uniform(0.03, 0.97)])

    while t < duration_s:
        kind = str(rng.choice(SEGMENTS, p=SEGMENT_P))
        if kind == "excursion" and count_out is None:
            kind = "move"
        segments.append((t, kind))
        if kind == "dwell":
            dt = float(rng.uniform(0.3, 1.5))
        elif kind == "move":
            new = on_screen()
            dt = float(rng.uniform(0.35, 1.2))
            aim = new
            if rng.random() < 0.3:
                roll = float(np.clip(roll + rng.normal(0, 6), -30, 30))
        elif kind == "sweep":
            new = on_screen()
            while np.linalg.norm(new - aim) < 0.35 * W:
                new = on_screen()
            target_blur = float(rng.uniform(0.3, 1.0)) * max_blur_px
            # peak speed of a minimum-jerk move: 1.875 x distance / duration
            ang = float(np.linalg.norm(new - aim)) / dist
            dt = max(0.12, 1.875 * ang * focal_px * exposure_s / target_blur)
            aim = new
        elif kind == "excursion":
            assert count_out is not None
            want = int(rng.choice([1, 2, 3], p=[0.35, 0.4, 0.25]))
            found = _excursion(rng, count_out, want, centre, cam, roll, screen_m)
            if found is None:
                segments[-1] = (t, "move")
                aim = on_screen()
                dt = float(rng.uniform(0.35, 1.2))
            else:
                dt = float(rng.uniform(0.3, 1.0))
                ts.append(t + dt)
                aims.append(found)
                cams.append(cam)
                rolls.append(roll)
                t += dt
                dt = float(rng.uniform(0.3, 1.5))  # stay out there
                ts.append(t + dt)
                aims.append(found)
                cams.append(cam)
                rolls.append(roll)
                t += dt
                aim = on_screen()  # and come back
                dt = float(rng.uniform(0.3, 1.0))
        elif kind == "distance":
            dist = float(np.clip(dist * rng.uniform(0.7, 1.4), *dist_range_m))
            cam = camera_at(centre, dist, theta, phi)
            dt = float(rng.uniform(0.6, 2.0))
        elif kind == "oblique":
            theta = float(rng.uniform(0, 45))
            phi = float(rng.uniform(0, 360))
            cam = camera_at(centre, dist, theta, phi)
            dt = float(rng.uniform(0.8, 2.5))
        else:  # roll
            roll = float(rng.uniform(-30, 30))
            dt = float(rng.uniform(0.4, 1.5))
        t += dt
        ts.append(t)
        aims.append(aim)
        cams.append(cam)
        rolls.append(roll)
    n = 3
    sway_amp = float(rng.uniform(0.001, 0.008)) * dist
    tremor_amp = math.radians(float(rng.uniform(0.02, 0.1)))
    sway = np.column_stack(
        [rng.uniform(0.1, 0.6, n), np.full(n, sway_amp / n), rng.uniform(0, 6.3, (n, 2))]
    )
    cam_sway = np.column_stack(
        [
            rng.uniform(0.1, 0.5, n),
            np.full(n, float(rng.uniform(0.001, 0.01))),
            rng.uniform(0, 6.3, (n, 2)),
        ]
    )
    tremor = np.column_stack(
        [rng.uniform(8, 12, n), np.full(n, tremor_amp / n), rng.uniform(0, 6.3, (n, 2))]
    )
    return Trajectory(
        np.array(ts),
        np.array(aims),
        np.array(cams),
        np.array(rolls),
        sway,
        cam_sway,
        tremor,
        tuple(segments),
    )


def _excursion(
    rng: np.random.Generator,
    count_out: CountOut,
    want: int,
    centre: FloatArray,
    cam: FloatArray,
    roll: float,
    screen_m: tuple[float, float],
) -> FloatArray | None:
    """An aim point (2,) past the screen's edge (want 2) or corner (1 or 3+) where
    exactly ``want`` (3: three or four) landmarks are out of the picture, or None."""
    W, H = screen_m
    if want == 2:
        ang = float(rng.choice([0.0, 90.0, 180.0, 270.0]) + rng.normal(0, 8))
    else:
        ang = float(rng.choice([45.0, 135.0, 225.0, 315.0]) + rng.normal(0, 10))
    d = np.array([math.cos(math.radians(ang)) * W, math.sin(math.radians(ang)) * H])
    lams = np.linspace(0.0, 2.0, 81)
    good = []
    for lam in lams:
        a = centre[:2] + lam * d
        k = count_out(np.array([a[0], a[1], 0.0]), cam, roll)
        if (k == want) or (want == 3 and k >= 3):
            good.append(lam)
        elif good and k > want:
            break
    if not good:
        return None
    lo, hi = good[0], good[-1]
    if want == 3:
        hi = min(hi, lo + 0.4)
    lam = float(rng.uniform(lo, hi))
    out: FloatArray = centre[:2] + lam * d
    return out
