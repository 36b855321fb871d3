"""A fixed camera watching a display / projection screen, rendered with exact truth.

The fixture renderer of issue 5 (dissertation ch. 5): the three calibration
patterns, a re-captured dot pattern, and laser-pointer videos, each with the
exact image <-> screen mapping.

Frames and units:

- *world* (metres): the screen plane z = 0, origin at the top-left corner of
  the screen's lit area (the corner of its top-left pixel), x right, y down,
  z into the screen (away from the viewer).
- *camera*: OpenCV's (x right, y down, z along the optical axis);
  ``X_cam = R @ X_world + t``.
- *screen pixels* (x, y): centre of the top-left pixel = (0, 0);
  ``X = (x + 0.5) * pitch_x`` with ``pitch = screen_m / screen_px``.
- *image pixels* (u, v): centre of the top-left pixel = (0, 0). Lens: OpenCV's
  radial model on normalized coordinates, ``x_d = x (1 + k1 r^2 + k2 r^4)``,
  ``u = fx x_d + cx`` (as :mod:`omnidev.sim.handcam`).

Light (grey levels, before sensor noise, per colour channel): inside the lit
area ``V (A rho + E (P_black + (P_white - P_black) s / 255) wb)`` with the
screen content ``s``; outside ``V A rho`` (the unlit screen fabric, its black
frame, the wall with posters). ``V`` is vignetting (``1 - vignetting (r/r_corner)^2``
over the image), ``A`` the uneven room light (an exponential ramp of strength
``light_gradient`` in a seeded direction), ``E`` the projector's brightness
(a hot spot), ``rho`` the reflectance, ``wb`` the projector's white balance.
Each camera pixel is the mean over ``supersample^2`` sub-pixel rays (so edges
are antialiased); sensor noise is Gaussian, ``noise_sigma`` grey levels.

A laser spot is extra light on the screen plane: a core so bright it clips
to white on the camera and a halo of the laser's colour (:class:`Spot`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.atomic import atomic_dir, check_output_dir
from omnidev.errors import OutputError
from omnidev.screencal.patterns import DotGrid, black_pattern, dot_pattern, white_pattern
from omnidev.sim.handcam import look_at
from omnidev.sim.screen_content import SLIDE_KINDS, laser_path, slide

FloatArray = NDArray[np.float64]
SCREEN_PX = (1920, 1080)
SCREEN_M = (1.60, 0.90)  # a projection screen's lit area, m
FABRIC_M = 0.06  # unlit screen fabric beyond the lit area, m
FRAME_M = 0.05  # the screen's black frame beyond the fabric, m
SUPERSAMPLE = 3
# Light levels (grey levels before vignetting)
AMBIENT = 62.0  # room light on a reflectance-1 surface at the screen centre
P_BLACK, P_WHITE = 8.0, 172.0  # projector black and white levels at E = 1
WHITE_BALANCE = (0.97, 1.0, 0.95)  # B, G, R gain of the projector's white
SPOT_CORE, SPOT_HALO = 6000.0, 220.0  # laser peak levels (power 1)
SPOT_COLOURS = {"red": (0.10, 0.16, 1.0), "green": (0.30, 1.0, 0.22)}  # B, G, R


@dataclass(frozen=True, eq=False)
class ScreenRig:
    """A fixed camera looking at a screen: intrinsics, pose, screen, light, noise.

    ``width, height``: camera image (px). ``fx, fy, cx, cy`` (px), ``k1, k2``:
    OpenCV radial model. ``R`` (3x3), ``t`` (3,): world -> camera. ``screen_px``:
    the screen's resolution; ``screen_m``: the lit area (m). ``vignetting``:
    relative fall-off at the image corners; ``light_gradient``: strength of the
    room light's ramp; ``noise_sigma``: grey levels; ``seed``: the room's
    texture and the light's direction.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float
    k2: float
    R: FloatArray
    t: FloatArray
    screen_px: tuple[int, int] = SCREEN_PX
    screen_m: tuple[float, float] = SCREEN_M
    vignetting: float = 0.3
    light_gradient: float = 0.35
    noise_sigma: float = 1.5
    seed: int = 0

    def camera_matrix(self) -> FloatArray:
        """The 3x3 camera matrix K (px)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def distortion(self) -> FloatArray:
        """OpenCV's distortion vector (k1, k2, p1, p2, k3) = (k1, k2, 0, 0, 0)."""
        return np.array([self.k1, self.k2, 0.0, 0.0, 0.0])

    def pitch(self) -> tuple[float, float]:
        """Screen pixel pitch (m per px) along x and y."""
        return self.screen_m[0] / self.screen_px[0], self.screen_m[1] / self.screen_px[1]

    def camera_center(self) -> FloatArray:
        """The camera centre in world coordinates (m)."""
        out: FloatArray = -self.R.T @ self.t
        return out

    def key(self) -> bytes:
        """Bytes identifying everything the rendering depends on (a cache key)."""
        scal = (
            self.width,
            self.height,
            self.fx,
            self.fy,
            self.cx,
            self.cy,
            self.k1,
            self.k2,
            *self.screen_px,
            *self.screen_m,
            self.vignetting,
            self.light_gradient,
            self.seed,
        )
        return repr(scal).encode() + self.R.tobytes() + self.t.tobytes()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters (with K and OpenCV's distortion vector for reference)."""
        return {
            "width": self.width,
            "height": self.height,
            "fx": self.fx,
            "fy": self.fy,
            "cx": self.cx,
            "cy": self.cy,
            "k1": self.k1,
            "k2": self.k2,
            "R": self.R.tolist(),
            "t": self.t.tolist(),
            "screen_px": list(self.screen_px),
            "screen_m": list(self.screen_m),
            "vignetting": self.vignetting,
            "light_gradient": self.light_gradient,
            "noise_sigma": self.noise_sigma,
            "seed": self.seed,
            "camera_matrix": self.camera_matrix().tolist(),
            "distortion": self.distortion().tolist(),
            "camera_center_m": self.camera_center().tolist(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ScreenRig:
        """The rig :meth:`to_dict` wrote (extra keys ignored)."""
        return cls(
            int(d["width"]),
            int(d["height"]),
            float(d["fx"]),
            float(d["fy"]),
            float(d["cx"]),
            float(d["cy"]),
            float(d["k1"]),
            float(d["k2"]),
            np.asarray(d["R"], float).reshape(3, 3),
            np.asarray(d["t"], float).reshape(3),
            (int(d["screen_px"][0]), int(d["screen_px"][1])),
            (float(d["screen_m"][0]), float(d["screen_m"][1])),
            float(d["vignetting"]),
            float(d["light_gradient"]),
            float(d["noise_sigma"]),
            int(d["seed"]),
        )


# ---------------------------------------------------------------- geometry


def _radial(k1: float, k2: float, r: FloatArray) -> FloatArray:
    r2 = r * r
    out: FloatArray = r * (1.0 + k1 * r2 + k2 * r2 * r2)
    return out


def radial_is_monotonic(k1: float, k2: float, r_max: float) -> bool:
    """Whether r (1 + k1 r^2 + k2 r^4) increases on [0, r_max] (normalized radius)."""
    s = np.linspace(0.0, r_max * r_max, 4001)
    return bool(np.all(1.0 + 3.0 * k1 * s + 5.0 * k2 * s * s > 0))


def _undistort_radius(k1: float, k2: float, rd: FloatArray, newton: int) -> FloatArray:
    """The undistorted radius r with r (1 + k1 r^2 + k2 r^4) = rd (a table, then Newton)."""
    top = float(np.max(rd, initial=0.0))
    hi = max(top, 1e-3)
    while _radial(k1, k2, np.array([hi]))[0] < top:
        hi *= 1.5
    r_tab = np.linspace(0.0, hi, 20001)
    r = np.interp(rd, _radial(k1, k2, r_tab), r_tab)
    for _ in range(newton):
        r2 = r * r
        f = r * (1.0 + k1 * r2 + k2 * r2 * r2) - rd
        r = r - f / (1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2)
    return r


def _pixels_to_normalized(rig: ScreenRig, uv: FloatArray, newton: int = 4) -> FloatArray:
    xd = (uv[..., 0] - rig.cx) / rig.fx
    yd = (uv[..., 1] - rig.cy) / rig.fy
    rd = np.hypot(xd, yd)
    r = _undistort_radius(rig.k1, rig.k2, rd, newton)
    scale = np.where(rd > 0, r / np.where(rd > 0, rd, 1.0), 1.0)
    return np.stack([xd * scale, yd * scale], -1)


def _plane_from_normalized(rig: ScreenRig) -> FloatArray:
    """3x3 homography: undistorted normalized (x, y, 1) -> world (X, Y, 1) on z = 0."""
    H = np.column_stack([rig.R[:, 0], rig.R[:, 1], rig.t])
    out: FloatArray = np.linalg.inv(H)
    return out


def image_to_screen(rig: ScreenRig, uv: FloatArray) -> FloatArray:
    """Image pixels (N, 2) -> screen pixels (N, 2), exact; NaN where the ray misses the plane.

    Undistortion by a table then Newton (residual ~1e-15 in normalized
    coordinates). Points outside the lit area get screen coordinates outside
    [0, W-1] x [0, H-1] (the plane continues).
    """
    uv = np.asarray(uv, float).reshape(-1, 2)
    xy = _pixels_to_normalized(rig, uv)
    C = rig.camera_center()
    d = np.column_stack([xy, np.ones(len(xy))]) @ rig.R  # world ray directions R^T (x, y, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -C[2] / d[:, 2]
    ok = np.isfinite(s) & (s > 0)
    X = C[0] + s * d[:, 0]
    Y = C[1] + s * d[:, 1]
    px, py = rig.pitch()
    out = np.column_stack([X / px - 0.5, Y / py - 0.5])
    out[~ok] = np.nan
    return out


def screen_to_image(rig: ScreenRig, xy: FloatArray) -> FloatArray:
    """Screen pixels (N, 2) -> image pixels (N, 2); NaN for points behind the camera."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    px, py = rig.pitch()
    Xw = np.column_stack([(xy[:, 0] + 0.5) * px, (xy[:, 1] + 0.5) * py, np.zeros(len(xy))])
    Xc = Xw @ rig.R.T + rig.t
    front = Xc[:, 2] > 1e-9
    z = np.where(front, Xc[:, 2], 1.0)
    n = Xc[:, :2] / z[:, None]
    r2 = np.sum(n * n, axis=1, keepdims=True)
    d = n * (1.0 + rig.k1 * r2 + rig.k2 * r2 * r2)
    out = np.column_stack([rig.fx * d[:, 0] + rig.cx, rig.fy * d[:, 1] + rig.cy])
    out[~front] = np.nan
    return out


def screen_border_image(rig: ScreenRig, per_side: int = 200) -> FloatArray:
    """The lit area's outline in image pixels (4 * per_side, 2), clockwise from top-left."""
    W, H = rig.screen_px
    s = np.linspace(0.0, 1.0, per_side, endpoint=False)
    x0, x1, y0, y1 = -0.5, W - 0.5, -0.5, H - 0.5
    pts = np.concatenate(
        [
            np.column_stack([x0 + s * (x1 - x0), np.full_like(s, y0)]),
            np.column_stack([np.full_like(s, x1), y0 + s * (y1 - y0)]),
            np.column_stack([x1 - s * (x1 - x0), np.full_like(s, y1)]),
            np.column_stack([np.full_like(s, x0), y1 - s * (y1 - y0)]),
        ]
    )
    return screen_to_image(rig, pts)


def _pose(k1: float, k2: float, size: tuple[int, int], tilt_deg: float, D: float) -> ScreenRig:
    W, H = size
    f = 0.9 * W
    centre = np.array([SCREEN_M[0] / 2, SCREEN_M[1] / 2, 0.0])
    yaw, pitch = math.radians(tilt_deg), math.radians(0.4 * tilt_deg)
    C = centre + D * np.array(
        [math.sin(yaw) * math.cos(pitch), -math.sin(pitch), -math.cos(yaw) * math.cos(pitch)]
    )
    pose = look_at(C, centre, roll_deg=1.0)
    return ScreenRig(
        W,
        H,
        f,
        f,
        (W - 1) / 2 + 0.01 * W,
        (H - 1) / 2 - 0.008 * H,
        k1,
        k2,
        pose.R.copy(),
        -pose.R @ C,
    )


def screen_rig(
    size: tuple[int, int] = (1280, 720), k1: float = -0.25, *, tilt_deg: float = 15.0, seed: int = 0
) -> ScreenRig:
    """A camera (58 degrees across) watching a 1.6 x 0.9 m screen from the side and above.

    The camera sits ``tilt_deg`` to the right of the screen's normal and
    ``0.4 tilt_deg`` above it, rolled 1 degree, aimed at the screen centre; the
    principal point is 1 % right and 0.8 % up of the image centre. Its distance
    is chosen so the screen spans 82 % of the image width or 86 % of its
    height, whichever is reached first, leaving the room visible around it.
    ``k2 = k1^2 / 2`` keeps the radial model increasing for every radius
    (1 + 3 k1 s + 5 k2 s^2 > 0 for all s when k2 > 0.45 k1^2). ``seed`` sets
    the room's texture and the light's direction (not the geometry).

    Example:
        >>> rig = screen_rig((640, 480), k1=0.1)
        >>> round(rig.k2, 6), rig.screen_px
        (0.005, (1920, 1080))
    """
    W, H = int(size[0]), int(size[1])
    if W < 64 or H < 64:
        raise ValueError(f"camera size {W}x{H}: at least 64x64")
    if not -0.5 <= k1 <= 0.5:
        raise ValueError(f"k1 = {k1:g}: outside [-0.5, 0.5]")
    k2 = 0.5 * k1 * k1

    def fill(D: float) -> float:
        rig = _pose(k1, k2, (W, H), tilt_deg, D)
        b = screen_border_image(rig, 64)
        if not np.all(np.isfinite(b)):
            return math.inf
        fw = (b[:, 0].max() - b[:, 0].min()) / W
        fh = (b[:, 1].max() - b[:, 1].min()) / H
        return float(max(fw / 0.82, fh / 0.86))

    lo, hi = 0.3, 30.0
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if fill(mid) > 1.0 else (lo, mid)
    rig = _pose(k1, k2, (W, H), tilt_deg, hi)
    b = screen_border_image(rig, 64)
    if (
        b[:, 0].min() < 0.02 * W
        or b[:, 0].max() > 0.98 * W
        or b[:, 1].min() < 0.02 * H
        or (b[:, 1].max() > 0.98 * H)
    ):
        raise ValueError(f"tilt {tilt_deg:g} deg: the screen does not fit in the picture")
    return replace(rig, seed=seed)


# ---------------------------------------------------------------- rendering


@dataclass(frozen=True)
class Spot:
    """A laser spot on the screen: centre (screen px), colour, radius (screen px), power.

    Its light on the screen plane at distance d (screen px) from the centre is
    ``power * (6000 exp(-d^2 / (2 (0.4 r)^2)) + 220 exp(-d^2 / (2 r^2)))`` grey
    levels per unit colour weight; red weighs (B, G, R) = (0.10, 0.16, 1.0),
    green (0.30, 1.0, 0.22): the core clips to white, the halo is coloured.
    """

    x: float
    y: float
    colour: str = "red"
    radius_px: float = 6.0
    power: float = 1.0


@dataclass
class _Prepared:
    mapx: NDArray[np.float32]  # supersampled screen x + 1 (padding), -100 outside the lit area
    mapy: NDArray[np.float32]
    gain: NDArray[np.float32]  # (H, W, 3): grey levels per unit of screen content
    offset: NDArray[np.float32]  # (H, W, 3): the picture of an all-black screen
    vign: NDArray[np.float32]  # (H, W)


_CACHE: dict[bytes, _Prepared] = {}


def _room_texture(
    rig: ScreenRig, x0: float, y0: float, x1: float, y1: float, texel: float
) -> NDArray[np.float32]:
    """Reflectance (BGR, 0..1) of the plane z = 0 over [x0, x1] x [y0, y1] m at ``texel`` m."""
    rng = np.random.default_rng([rig.seed, 9091])
    tw, th = math.ceil((x1 - x0) / texel) + 1, math.ceil((y1 - y0) / texel) + 1
    low = cv2.resize(
        rng.normal(0.0, 0.06, (8, 12)).astype(np.float32), (tw, th), interpolation=cv2.INTER_CUBIC
    )
    grain = rng.normal(0.0, 0.02, (th, tw)).astype(np.float32)
    wall = 0.85 + low + grain
    tex = np.stack([wall * 0.92, wall * 0.97, wall], -1)

    def box(ax0: float, ay0: float, ax1: float, ay1: float, col: tuple[float, ...]) -> None:
        c0, r0 = int((ax0 - x0) / texel), int((ay0 - y0) / texel)
        c1, r1 = int((ax1 - x0) / texel), int((ay1 - y0) / texel)
        c0, c1 = max(c0, 0), min(c1, tw)
        r0, r1 = max(r0, 0), min(r1, th)
        if c1 > c0 and r1 > r0:
            tex[r0:r1, c0:c1] = col

    sw, sh = rig.screen_m
    # posters, a door, a red exit sign: left, right, above, below the screen
    box(-0.75, 0.05, -0.35, 0.60, (0.30, 0.55, 0.90))
    box(sw + 0.30, -0.40, sw + 0.90, 1.60, (0.45, 0.40, 0.38))
    box(sw + 0.35, 0.10, sw + 0.55, 0.18, (0.05, 0.05, 0.95))
    box(0.20, -0.55, 0.60, -0.30, (0.80, 0.80, 0.80))
    box(-0.40, sh + 0.30, sw + 0.40, sh + 0.40, (0.15, 0.18, 0.20))
    f, fr = FABRIC_M, FABRIC_M + FRAME_M
    box(-fr, -fr, sw + fr, sh + fr, (0.06, 0.06, 0.06))
    box(-f, -f, sw + f, sh + f, (0.80, 0.80, 0.80))
    out: NDArray[np.float32] = np.clip(tex, 0.0, 1.0).astype(np.float32)
    return out


def _prepare(rig: ScreenRig) -> _Prepared:
    key = rig.key()
    if key in _CACHE:
        return _CACHE[key]
    n = SUPERSAMPLE
    W, H = rig.width, rig.height
    SW, SH = rig.screen_px
    px, py = rig.pitch()
    Hp = _plane_from_normalized(rig)
    offs = (np.arange(n) + 0.5) / n - 0.5
    us = (np.arange(W)[:, None] + offs[None, :]).ravel()
    mapx = np.empty((H * n, W * n), np.float32)
    mapy = np.empty((H * n, W * n), np.float32)
    Xw = np.empty((H * n, W * n), np.float32)
    Yw = np.empty((H * n, W * n), np.float32)
    front = np.empty((H * n, W * n), bool)
    rows = (np.arange(H)[:, None] + offs[None, :]).ravel()
    for a in range(0, len(rows), 256):  # in bands, to bound memory
        vv, uu = np.meshgrid(rows[a : a + 256], us, indexing="ij")
        xy = _pixels_to_normalized(rig, np.stack([uu, vv], -1), newton=0)
        w = Hp[2, 0] * xy[..., 0] + Hp[2, 1] * xy[..., 1] + Hp[2, 2]
        ok = w > 0
        winv = 1.0 / np.where(ok, w, 1.0)
        X = (Hp[0, 0] * xy[..., 0] + Hp[0, 1] * xy[..., 1] + Hp[0, 2]) * winv
        Y = (Hp[1, 0] * xy[..., 0] + Hp[1, 1] * xy[..., 1] + Hp[1, 2]) * winv
        sx, sy = X / px - 0.5, Y / py - 0.5
        inside = ok & (sx >= -0.5) & (sx <= SW - 0.5) & (sy >= -0.5) & (sy <= SH - 0.5)
        mapx[a : a + 256] = np.where(inside, sx + 1.0, -100.0)
        mapy[a : a + 256] = np.where(inside, sy + 1.0, -100.0)
        Xw[a : a + 256], Yw[a : a + 256], front[a : a + 256] = X, Y, ok
    cov = cv2.resize((mapx > -50).astype(np.float32), (W, H), interpolation=cv2.INTER_AREA)
    # the room: a reflectance texture over the visible part of the plane
    vis = front & (np.abs(Xw) < 50) & (np.abs(Yw) < 50)
    x0, x1 = float(Xw[vis].min()) - 0.01, float(Xw[vis].max()) + 0.01
    y0, y1 = float(Yw[vis].min()) - 0.01, float(Yw[vis].max()) + 0.01
    texel = max((x1 - x0) / 4000, (y1 - y0) / 4000, 0.001)
    tex = _room_texture(rig, x0, y0, x1, y1, texel)
    rx = np.where(vis, (Xw - x0) / texel, -100.0).astype(np.float32)
    ry = np.where(vis, (Yw - y0) / texel, -100.0).astype(np.float32)
    del Xw, Yw
    room_ss = cv2.remap(
        tex, rx, ry, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=(0.3, 0.3, 0.3)
    )
    del rx, ry
    room = cv2.resize(room_ss, (W, H), interpolation=cv2.INTER_AREA)
    # light fields at pixel centres
    vv, uu = np.mgrid[0:H, 0:W].astype(np.float64)
    wxy = image_to_screen(rig, np.stack([uu.ravel(), vv.ravel()], -1)).reshape(H, W, 2)
    wxy = np.nan_to_num(wxy, nan=0.0)
    nx = (wxy[..., 0] + 0.5) / SW * 2 - 1  # -1..1 across the screen
    ny = (wxy[..., 1] + 0.5) / SH * 2 - 1
    rng = np.random.default_rng([rig.seed, 4242])
    ang = rng.uniform(0, 2 * math.pi)
    ramp = np.clip(math.cos(ang) * nx + math.sin(ang) * ny, -3, 3)
    ambient = AMBIENT * np.exp(0.5 * rig.light_gradient * ramp)
    hx, hy = rng.uniform(-0.2, 0.2), rng.uniform(-0.3, 0.0)
    proj = np.exp(-((nx - hx) ** 2 + ((ny - hy) * SH / SW) ** 2) / (2 * 1.3**2))
    proj *= np.exp(0.15 * rig.light_gradient * ramp)
    rc = max(
        math.hypot(cx, cy) for cx in (rig.cx, W - 1 - rig.cx) for cy in (rig.cy, H - 1 - rig.cy)
    )
    vign = 1.0 - rig.vignetting * ((uu - rig.cx) ** 2 + (vv - rig.cy) ** 2) / rc**2
    wb = np.array(WHITE_BALANCE)
    gain = (vign * proj)[..., None] * ((P_WHITE - P_BLACK) / 255.0) * wb
    offset = vign[..., None] * (ambient[..., None] * room + (proj * P_BLACK * cov)[..., None] * wb)
    prep = _Prepared(
        mapx, mapy, gain.astype(np.float32), offset.astype(np.float32), vign.astype(np.float32)
    )
    if len(_CACHE) >= 3:
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[key] = prep
    return prep


def _spot_light(
    rig: ScreenRig, spot: Spot, vign: NDArray[np.float32]
) -> tuple[slice, slice, NDArray[np.float32]]:
    """The spot's light (h, w, 3) in its image window (rows, cols), box-filtered per pixel."""
    if spot.colour not in SPOT_COLOURS:
        raise ValueError(f"spot colour {spot.colour!r}: 'red' or 'green'")
    r = spot.radius_px
    ext = 4.0 * r + 2.0
    corners = np.array(
        [[spot.x + a * ext, spot.y + b * ext] for a in (-1, 0, 1) for b in (-1, 0, 1)]
    )
    uv = screen_to_image(rig, corners)
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    if len(uv) == 0:
        return slice(0, 0), slice(0, 0), np.zeros((0, 0, 3), np.float32)
    c0 = max(math.floor(uv[:, 0].min()) - 1, 0)
    c1 = min(math.ceil(uv[:, 0].max()) + 2, rig.width)
    r0 = max(math.floor(uv[:, 1].min()) - 1, 0)
    r1 = min(math.ceil(uv[:, 1].max()) + 2, rig.height)
    if c1 <= c0 or r1 <= r0:
        return slice(0, 0), slice(0, 0), np.zeros((0, 0, 3), np.float32)
    n = SUPERSAMPLE
    offs = (np.arange(n) + 0.5) / n - 0.5
    us = (np.arange(c0, c1)[:, None] + offs[None, :]).ravel()
    vs = (np.arange(r0, r1)[:, None] + offs[None, :]).ravel()
    vv, uu = np.meshgrid(vs, us, indexing="ij")
    sxy = image_to_screen(rig, np.stack([uu.ravel(), vv.ravel()], -1))
    d2 = (sxy[:, 0] - spot.x) ** 2 + (sxy[:, 1] - spot.y) ** 2
    d2 = np.nan_to_num(d2, nan=1e12)
    level = spot.power * (
        SPOT_CORE * np.exp(-d2 / (2 * (0.4 * r) ** 2)) + SPOT_HALO * np.exp(-d2 / (2 * r * r))
    )
    h, w = r1 - r0, c1 - c0
    level = level.reshape(h, n, w, n).mean(axis=(1, 3)) * vign[r0:r1, c0:c1]
    light = level[..., None] * np.array(SPOT_COLOURS[spot.colour])
    return slice(r0, r1), slice(c0, c1), light.astype(np.float32)


def render(
    rig: ScreenRig,
    screen_image: NDArray[np.uint8],
    *,
    spot: Spot | None = None,
    frame_seed: int = 0,
    noise: bool = True,
) -> NDArray[np.uint8]:
    """The camera's picture (height x width x 3, BGR uint8) of the screen showing ``screen_image``.

    Args:
        rig: the camera, screen and light.
        screen_image: ``screen_px[1] x screen_px[0]`` grey or BGR uint8.
        spot: a laser spot on the screen, or None.
        frame_seed: with ``rig.seed``, the sensor noise of this frame.
        noise: False renders without sensor noise (for truth tests).
    """
    SW, SH = rig.screen_px
    if screen_image.shape[:2] != (SH, SW) or screen_image.dtype != np.uint8:
        raise ValueError(
            f"screen image {screen_image.shape} {screen_image.dtype}: expected uint8 {SH}x{SW}"
            " (grey) or {SH}x{SW}x3 (BGR)"
        )
    prep = _prepare(rig)
    padded = cv2.copyMakeBorder(screen_image, 1, 1, 1, 1, cv2.BORDER_REPLICATE)
    ss = cv2.remap(
        padded,
        prep.mapx,
        prep.mapy,
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    content = cv2.resize(ss, (rig.width, rig.height), interpolation=cv2.INTER_AREA)
    c = content.astype(np.float32)
    if c.ndim == 2:
        c = c[..., None]
    img = prep.offset + prep.gain * c
    if spot is not None:
        rows, cols, light = _spot_light(rig, spot, prep.vign)
        img[rows, cols] += light
    if noise and rig.noise_sigma > 0:
        rng = np.random.default_rng([rig.seed, frame_seed, 31337])
        img += rng.standard_normal(img.shape, dtype=np.float32) * np.float32(rig.noise_sigma)
    out: NDArray[np.uint8] = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    return out


# ---------------------------------------------------------------- videos and fixtures


def laser_video(
    rig: ScreenRig, frames: int, *, fps: float = 30.0, colour: str = "red", seed: int = 0
) -> Iterator[tuple[NDArray[np.uint8], Spot | None, NDArray[np.uint8]]]:
    """Frames of a laser spot moving over changing slides: (picture, spot or None, screen content).

    The path is :func:`omnidev.sim.screen_content.laser_path` (moves, pauses,
    jumps, >= 12 % of frames without a spot, targets near the border); the
    slides (:data:`~omnidev.sim.screen_content.SLIDE_KINDS`, in a seeded order)
    change every 0.7-1.3 s and carry small bright red and green details that
    are not the laser, plus an animated red ball and a blinking green dot.
    """
    if colour not in SPOT_COLOURS:
        raise ValueError(f"laser colour {colour!r}: 'red' or 'green'")
    SW, SH = rig.screen_px
    path = laser_path(frames, SW, SH, fps=fps, seed=seed)
    rng = np.random.default_rng([seed, 808])
    order = [SLIDE_KINDS[i] for i in rng.permutation(len(SLIDE_KINDS))]
    changes: list[int] = []
    k = 0
    while k < frames:
        changes.append(k)
        k += max(1, int(rng.uniform(0.7, 1.3) * fps))
    for i in range(frames):
        which = sum(1 for c in changes if c <= i) - 1
        content = slide(order[which % len(order)], SW, SH, i / fps, seed)
        p = path[i]
        spot = None if p is None else Spot(p.x, p.y, colour, 6.0, p.power)
        yield render(rig, content, spot=spot, frame_seed=1000 + i), spot, content


def recaptured_rig(rig: ScreenRig) -> ScreenRig:
    """The rig after a small disturbance, as between Fig. 5.13 and Fig. 5.14.

    The camera turned by 0.03 degrees (about an axis in the image plane) and
    re-focused (focal length +0.15 %); the picture shifts by about half a pixel.
    """
    a = math.radians(0.03)
    axis = np.array([0.6, 0.8, 0.0])
    dR, _ = cv2.Rodrigues(axis * a)
    R = dR @ rig.R
    C = rig.camera_center()
    return replace(rig, R=R, t=-R @ C, fx=rig.fx * 1.0015, fy=rig.fy * 1.0015)


def make_screen_fixture(
    outdir: Path,
    *,
    size: tuple[int, int] = (1280, 720),
    k1: float = -0.25,
    n: int = 9,
    frames: int = 120,
    colour: str = "red",
    seed: int = 0,
    force: bool = False,
) -> dict[str, Any]:
    """Render a screen-calibration + laser fixture folder atomically; returns truth.json.

    Files: white.png, black.png, dots.png (the camera's pictures of the three
    patterns, 8-bit grey: the BGR render through cv2.COLOR_BGR2GRAY, to keep
    the files small), dots_recaptured.png (the dot pattern after
    :func:`recaptured_rig`), laser.avi (MJPG, quality 85, 30 fps) and
    truth.json (both rigs, the dot grid with its image positions, per frame
    the spot's screen and image position or null, the regenerate command).
    """
    if colour not in SPOT_COLOURS:
        raise OutputError(f"laser colour {colour!r}: 'red' or 'green'")
    outdir = Path(outdir)
    check_output_dir(outdir, force=force)
    rig = screen_rig(size, k1, seed=seed)
    rig2 = recaptured_rig(rig)
    SW, SH = rig.screen_px
    dots, grid = dot_pattern(SW, SH, n)
    fps = 30.0
    with atomic_dir(outdir, force=force) as tmp:
        shots = (
            ("white.png", rig, white_pattern(SW, SH)),
            ("black.png", rig, black_pattern(SW, SH)),
            ("dots.png", rig, dots),
            ("dots_recaptured.png", rig2, dots),
        )
        for k, (name, r, pattern) in enumerate(shots):
            grey = cv2.cvtColor(render(r, pattern, frame_seed=k + 1), cv2.COLOR_BGR2GRAY)
            cv2.imwrite(str(tmp / name), grey, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        video = cv2.VideoWriter(str(tmp / "laser.avi"), cv2.VideoWriter.fourcc(*"MJPG"), fps, size)
        if not video.isOpened():
            raise OutputError(f"cannot write MJPG video in {tmp}")
        video.set(cv2.VIDEOWRITER_PROP_QUALITY, 85)
        per_frame: list[dict[str, Any]] = []
        for i, (img, spot, _) in enumerate(
            laser_video(rig, frames, fps=fps, colour=colour, seed=seed)
        ):
            video.write(img)
            if spot is None:
                per_frame.append({"index": i, "spot": None, "spot_image": None})
            else:
                uv = screen_to_image(rig, np.array([[spot.x, spot.y]]))[0]
                per_frame.append(
                    {
                        "index": i,
                        "spot": [spot.x, spot.y],
                        "spot_image": uv.tolist(),
                        "power": spot.power,
                    }
                )
        video.release()
        doc = _truth_doc(rig, rig2, grid, per_frame, colour, fps)
        doc["regenerate"] = (
            f"omnidev sim screen {outdir} --size {size[0]}x{size[1]} --k1 {k1:+.2f} --n {n} "
            f"--frames {frames} --colour {colour} --seed {seed} --force"
        )
        (tmp / "truth.json").write_text(json.dumps(doc, indent=1) + "\n")
    return doc


def _truth_doc(
    rig: ScreenRig,
    rig2: ScreenRig,
    grid: DotGrid,
    per_frame: list[dict[str, Any]],
    colour: str,
    fps: float,
) -> dict[str, Any]:
    SW, SH = rig.screen_px
    corners = np.array([[-0.5, -0.5], [SW - 0.5, -0.5], [SW - 0.5, SH - 0.5], [-0.5, SH - 0.5]])
    return {
        "conventions": (
            "image and screen pixels: centre of the top-left pixel = (0,0), x/u right, y/v down; "
            "world: metres, screen plane z=0, origin at the lit area's top-left corner, x right, "
            "y down, z into the screen; X_cam = R X_world + t; screen px x = X/pitch - 0.5; "
            "lens: OpenCV radial k1, k2 on normalized coordinates"
        ),
        "rig": rig.to_dict(),
        "recaptured_rig": rig2.to_dict(),
        "recaptured_note": "dots_recaptured.png: camera turned 0.03 deg and refocused "
        "(f +0.15 %); same room and light, new noise",
        "screen_corners_image": screen_to_image(rig, corners).tolist(),
        "dots": {
            "n": grid.n,
            "polarity": grid.polarity,
            "radius_px": grid.radius_px,
            "spacing_px": list(grid.spacing_px),
            "centers": grid.centers.tolist(),
            "centers_image": screen_to_image(rig, grid.centers).tolist(),
            "centers_image_recaptured": screen_to_image(rig2, grid.centers).tolist(),
        },
        "files": {
            "white.png": "white-rectangle pattern, grey (frame_seed 1)",
            "black.png": "black-rectangle pattern, grey (frame_seed 2)",
            "dots.png": "dot-matrix pattern (white dots on black), grey (frame_seed 3)",
            "dots_recaptured.png": "dot-matrix pattern seen by recaptured_rig, grey (frame_seed 4)",
            "laser.avi": "laser spot video, MJPG quality 85",
        },
        "laser": {
            "colour": colour,
            "fps": fps,
            "frames": len(per_frame),
            "radius_px": 6.0,
            "frames_without_spot": sum(1 for f in per_frame if f["spot"] is None),
            "per_frame": per_frame,
        },
    }


def load_screen_fixture(folder: Path) -> tuple[ScreenRig, dict[str, Any]]:
    """The rig and the truth document of a folder :func:`make_screen_fixture` wrote."""
    doc: dict[str, Any] = json.loads((Path(folder) / "truth.json").read_text())
    return ScreenRig.from_dict(doc["rig"]), doc
