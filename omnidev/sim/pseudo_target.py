"""Scenes for the non-SVP renderer, ray-cast exactly in the mirror frame (millimetres).

Frame: the mirror coordinate system of dissertation sec. 2.3.3: origin at the
mirror's focus O_m, z along the mirror axis pointing from the camera towards the
mirror (up), x and y horizontal, right-handed. The scenes lie below and around
the mirror, as in sec. 2.5.1 ("the target was laid under our hypercatadioptric
camera").

- :class:`PseudoTarget`: the pseudo target of Fig. 2.9: a 20 x 20 m ground plane
  2 m below O_m (its centre on the mirror axis, its normal along z) with a dark
  1 m grid, and an L-shaped wall 1 m high whose two arms are 2.8 m long.
- :class:`TexturedRoom`: fine detail for interpolation quality: a square room
  whose four walls *are* the four side view planes of sec. 2.5.1 (at sqrt(2) m
  from the axis, each spanning 90 degrees of azimuth) and whose floor is the top
  view plane (2 m below O_m), every surface carrying a sharp-edged texture
  (shapes, lines, letters) rasterised at 2 mm per texel and read bilinearly.

A scene answers :meth:`shade`: the BGR colour (float, 0..255) of the first
surface along each ray ``origins + t dirs``, t > 0, with the sky (a smooth
function of the direction only) where nothing is hit. Everything is a pure
function of the seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

GROUND_Z = -2000.0  # mm, the ground / floor plane (sec. 2.5.1: region centre 2 m below O_m)
SIDE_DISTANCE = 1000.0 * math.sqrt(2.0)  # mm, side view planes' distance from the z-axis
EPS = 1e-9


class NonSvpScene(Protocol):
    """What the renderer needs from a scene (mirror frame, mm)."""

    def shade(self, origins: FloatArray, dirs: FloatArray) -> FloatArray: ...

    def describe(self) -> dict[str, Any]: ...


def sky(dirs: FloatArray) -> FloatArray:
    """BGR sky colour for unit-ish directions (N, 3): a gradient by elevation."""
    dz = dirs[:, 2] / np.linalg.norm(dirs, axis=1)
    w = np.clip(0.5 + 0.5 * dz, 0.0, 1.0)[:, None]
    return np.asarray(
        (1 - w) * np.array([150.0, 140.0, 120.0]) + w * np.array([240.0, 200.0, 130.0])
    )


def _plane_hit(
    origins: FloatArray, dirs: FloatArray, normal: FloatArray, offset: float
) -> FloatArray:
    """Ray parameter t of the hit with the plane normal . p = offset (inf if none ahead)."""
    den = dirs @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (offset - origins @ normal) / den
    return np.where(np.isfinite(t) & (t > EPS), t, np.inf)


def _box_hit(
    origins: FloatArray, dirs: FloatArray, lo: FloatArray, hi: FloatArray
) -> tuple[FloatArray, NDArray[np.intp]]:
    """Entry distance into an axis-aligned box (inf if missed) and the entry face's axis."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - origins) / dirs
        t2 = (hi - origins) / dirs
    tmin = np.where(np.isnan(t1), -np.inf, np.minimum(t1, t2))
    tmax = np.where(np.isnan(t1), np.inf, np.maximum(t1, t2))
    axis = np.argmax(tmin, axis=1)
    t_near = tmin[np.arange(len(tmin)), axis]
    t_far = np.min(tmax, axis=1)
    ok = (t_near <= t_far) & (t_near > EPS)
    return np.where(ok, t_near, np.inf), axis.astype(np.intp)


@dataclass(frozen=True)
class PseudoTarget:
    """The pseudo target of Fig. 2.9 (mm, mirror frame).

    Ground: z = -2000, |x|, |y| <= 10000, tiles 1 m, tinted in a checker of two
    light greys, joints dark and ``line_width`` wide, except the joint along
    +x (y = 0, x > 0) drawn red and the one along +y drawn green (orientation).
    L-shaped wall: two boxes ``wall_thickness`` thick, 1000 high (z from -2000
    to -1000), arms 2800 long from the corner ``wall_corner`` towards +x and +y
    (outer faces at y = corner_y and x = corner_x); brick-red faces with dark
    vertical joints every 400 mm and a horizontal one at mid-height, light top.
    Beyond the ground: :func:`sky`.
    """

    wall_corner: tuple[float, float] = (-1200.0, 300.0)
    wall_length: float = 2800.0
    wall_height: float = 1000.0
    wall_thickness: float = 100.0
    half_extent: float = 10000.0
    line_width: float = 40.0

    def describe(self) -> dict[str, Any]:
        return {
            "type": "pseudo-target",
            "ground_z_mm": GROUND_Z,
            "ground_half_extent_mm": self.half_extent,
            "grid_mm": 1000.0,
            "line_width_mm": self.line_width,
            "wall_corner_mm": list(self.wall_corner),
            "wall_length_mm": self.wall_length,
            "wall_height_mm": self.wall_height,
            "wall_thickness_mm": self.wall_thickness,
            "walls": "boxes x in [cx, cx+L] y in [cy, cy+th] and x in [cx, cx+th] y in [cy, cy+L]",
        }

    def _boxes(self) -> list[tuple[FloatArray, FloatArray]]:
        cx, cy = self.wall_corner
        L, th = self.wall_length, self.wall_thickness
        z0, z1 = GROUND_Z, GROUND_Z + self.wall_height
        return [
            (np.array([cx, cy, z0]), np.array([cx + L, cy + th, z1])),
            (np.array([cx, cy, z0]), np.array([cx + th, cy + L, z1])),
        ]

    def shade(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        origins = np.broadcast_to(np.asarray(origins, np.float64), dirs.shape)
        out = sky(dirs)
        t_g = _plane_hit(origins, dirs, np.array([0.0, 0.0, 1.0]), GROUND_Z)
        t_g = np.where(origins[:, 2] > GROUND_Z, t_g, np.inf)
        best = t_g.copy()
        kind = np.zeros(len(dirs), np.intp)  # 0 sky, 1 ground, 2 wall side, 3 wall top
        kind[np.isfinite(t_g)] = 1
        axis_best = np.zeros(len(dirs), np.intp)
        for lo, hi in self._boxes():
            t_b, axis = _box_hit(origins, dirs, lo, hi)
            closer = t_b < best
            best = np.where(closer, t_b, best)
            kind[closer] = np.where(axis[closer] == 2, 3, 2)
            axis_best[closer] = axis[closer]
        p = origins + np.where(np.isfinite(best), best, 0.0)[:, None] * dirs
        g = (
            (kind == 1)
            & (np.abs(p[:, 0]) <= self.half_extent)
            & (np.abs(p[:, 1]) <= self.half_extent)
        )
        if np.any(g):
            out[g] = self._ground(p[g, 0], p[g, 1])
        w = kind == 2
        if np.any(w):
            s = np.where(axis_best[w] == 1, p[w, 0], p[w, 1])
            out[w] = self._wall(s, p[w, 2])
        top = kind == 3
        out[top] = np.array([200.0, 215.0, 235.0])
        return out

    def _ground(self, x: FloatArray, y: FloatArray) -> FloatArray:
        checker = (np.floor(x / 1000.0) + np.floor(y / 1000.0)) % 2
        col = np.where(checker[:, None] > 0, [[226.0, 226.0, 226.0]], [[196.0, 206.0, 214.0]])
        hw = self.line_width / 2
        on_x = np.abs(x - 1000.0 * np.round(x / 1000.0)) <= hw  # a joint x = k m
        on_y = np.abs(y - 1000.0 * np.round(y / 1000.0)) <= hw
        col[on_x | on_y] = 30.0
        col[(np.abs(y) <= hw) & (x > hw)] = [40.0, 40.0, 210.0]  # +x joint red
        col[(np.abs(x) <= hw) & (y > hw)] = [40.0, 170.0, 40.0]  # +y joint green
        return np.asarray(col, np.float64)

    def _wall(self, s: FloatArray, z: FloatArray) -> FloatArray:
        col = np.tile(np.array([70.0, 80.0, 175.0]), (len(s), 1))
        vert = np.abs(s - 400.0 * np.round(s / 400.0)) <= 15.0
        horiz = np.abs(z - (GROUND_Z + self.wall_height / 2)) <= 15.0
        col[vert | horiz] = 45.0
        return col


def _texture(rng: np.random.Generator, w_mm: float, h_mm: float, texel: float) -> NDArray[np.uint8]:
    """A sharp-edged random texture of w_mm x h_mm at ``texel`` mm per texel (BGR uint8)."""
    w, h = round(w_mm / texel), round(h_mm / texel)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32) * texel
    img = np.empty((h, w, 3), np.float32)
    base = rng.uniform(80, 180, 3)
    for ch in range(3):
        img[..., ch] = base[ch]
        for _ in range(3):
            wl = rng.uniform(60.0, 700.0)
            ang = rng.uniform(0, math.pi)
            k = 2 * math.pi / wl
            img[..., ch] += rng.uniform(8, 22) * np.sin(
                k * (math.cos(ang) * xx + math.sin(ang) * yy) + rng.uniform(0, 2 * math.pi)
            )
    canvas = np.clip(img, 0, 255).astype(np.uint8)
    px = 1.0 / texel

    def colour() -> tuple[int, int, int]:
        return tuple(int(v) for v in rng.integers(0, 256, 3))  # type: ignore[return-value]

    area = w_mm * h_mm / 1e6  # m^2
    for _ in range(int(4 * area)):  # rectangles 60..600 mm
        x0, y0 = rng.uniform(0, w_mm), rng.uniform(0, h_mm)
        rw, rh = rng.uniform(60, 600), rng.uniform(60, 600)
        cv2.rectangle(
            canvas,
            (int(x0 * px), int(y0 * px)),
            (int((x0 + rw) * px), int((y0 + rh) * px)),
            colour(),
            -1,
            cv2.LINE_AA,
        )
    for _ in range(int(5 * area)):  # discs 20..200 mm radius
        cx, cy, r = rng.uniform(0, w_mm), rng.uniform(0, h_mm), rng.uniform(20, 200)
        cv2.circle(canvas, (int(cx * px), int(cy * px)), int(r * px), colour(), -1, cv2.LINE_AA)
    for _ in range(int(1.5 * area)):  # lines 6..30 mm wide
        p0 = (int(rng.uniform(0, w_mm) * px), int(rng.uniform(0, h_mm) * px))
        p1 = (int(rng.uniform(0, w_mm) * px), int(rng.uniform(0, h_mm) * px))
        cv2.line(canvas, p0, p1, colour(), max(1, int(rng.uniform(6, 30) * px)), cv2.LINE_AA)
    letters = "ABCDEFGHKMNPRSTWXYZ0123456789"
    for _ in range(int(3 * area)):  # letters 60..250 mm high
        text = "".join(rng.choice(list(letters), int(rng.integers(2, 6))))
        size = rng.uniform(60, 250) * px / 22.0
        org = (int(rng.uniform(0, w_mm) * px), int(rng.uniform(0, h_mm) * px))
        cv2.putText(
            canvas,
            text,
            org,
            cv2.FONT_HERSHEY_SIMPLEX,
            size,
            colour(),
            max(1, int(size * 2)),
            cv2.LINE_AA,
        )
    return canvas


def _sample(tex: NDArray[np.uint8], s: FloatArray, t: FloatArray, texel: float) -> FloatArray:
    """Bilinear texture read at (s, t) mm (texel centres at (i + 0.5) texel), BGR float."""
    n = len(s)
    rows = -(-n // 4096)  # cv2.remap wants maps under 32767 rows/columns
    mx = np.zeros(rows * 4096, np.float32)
    my = np.zeros(rows * 4096, np.float32)
    mx[:n] = s / texel - 0.5
    my[:n] = t / texel - 0.5
    out = cv2.remap(
        tex,
        mx.reshape(rows, 4096),
        my.reshape(rows, 4096),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REFLECT,
    )
    return np.asarray(out.reshape(-1, 3)[:n], np.float64)


@dataclass(frozen=True)
class TexturedRoom:
    """A square room around the mirror axis whose walls are the four side view planes.

    Wall k (k = 0..3) is the plane n_k . p = sqrt(2) m with n_k at azimuth
    45 + 90 k degrees, spanning azimuths 90 k .. 90 (k + 1) degrees between the
    room's corners (at 2 m from the axis on the x and y axes) and z from -2000
    (the floor) to ``wall_top``; above it the sky. Wall texture coordinates: s
    (mm) along the wall from its corner at azimuth 90 (k + 1) degrees towards
    the one at 90 k degrees (the direction a person at the axis looking out sees
    as "right"), t = wall_top - z (mm, downwards). Floor: z = -2000, texture
    coordinates s = x + 2000, t = 2000 - y (mm). Textures are drawn at
    ``texel`` mm per texel from ``seed`` (see :func:`_texture`).
    """

    seed: int = 0
    texel: float = 2.0
    wall_top: float = 1500.0
    _tex: list[NDArray[np.uint8]] = field(default_factory=list, repr=False, compare=False)

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.seed)
        width = 2 * SIDE_DISTANCE
        for _ in range(4):
            self._tex.append(_texture(rng, width, self.wall_top - GROUND_Z, self.texel))
        self._tex.append(_texture(rng, 4000.0, 4000.0, self.texel))

    def describe(self) -> dict[str, Any]:
        return {
            "type": "textured-room",
            "seed": self.seed,
            "texel_mm": self.texel,
            "floor_z_mm": GROUND_Z,
            "wall_distance_mm": SIDE_DISTANCE,
            "wall_azimuths_deg": [45.0 + 90.0 * k for k in range(4)],
            "wall_top_mm": self.wall_top,
        }

    def shade(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        origins = np.broadcast_to(np.asarray(origins, np.float64), dirs.shape)
        out = sky(dirs)
        normals = [
            np.array([math.cos(a), math.sin(a), 0.0])
            for a in (math.radians(45.0 + 90.0 * k) for k in range(4))
        ]
        ts = [_plane_hit(origins, dirs, n, SIDE_DISTANCE) for n in normals]
        ts.append(_plane_hit(origins, dirs, np.array([0.0, 0.0, 1.0]), GROUND_Z))
        tt = np.stack(ts, 1)
        face = np.argmin(tt, axis=1)
        t = tt[np.arange(len(tt)), face]
        hit = np.isfinite(t)
        p = origins + np.where(hit, t, 0.0)[:, None] * dirs
        for k in range(4):
            sel = hit & (face == k) & (p[:, 2] <= self.wall_top)
            if not np.any(sel):
                continue
            a = math.radians(45.0 + 90.0 * k)
            right = np.array([math.sin(a), -math.cos(a), 0.0])
            corner = 2000.0 * np.array([math.cos(a + math.pi / 4), math.sin(a + math.pi / 4), 0.0])
            s = (p[sel] - corner) @ right
            out[sel] = _sample(self._tex[k], s, self.wall_top - p[sel, 2], self.texel)
        sel = hit & (face == 4)
        if np.any(sel):
            out[sel] = _sample(self._tex[4], p[sel, 0] + 2000.0, 2000.0 - p[sel, 1], self.texel)
        return out


def make_scene(name: str, seed: int = 0) -> NonSvpScene:
    """``pseudo-target`` or ``textured`` (a :class:`TexturedRoom` from ``seed``)."""
    if name == "pseudo-target":
        return PseudoTarget()
    if name == "textured":
        return TexturedRoom(seed)
    raise ValueError(f"unknown scene {name!r} (pseudo-target, textured)")
