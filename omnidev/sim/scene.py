"""Scenes for the renderer, ray-cast analytically in the camera frame (metres, z up).

Textures are procedural and band-limited: smooth colour fields and shapes whose
edges are blurred over a few centimetres, so that an omni-image of a few
hundred pixels resolves most of their detail and a truth image can be compared
with an unwarped one without aliasing deciding the result.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

BACKGROUND = np.array([40.0, 40.0, 40.0])


def smoothstep(edge0: float | FloatArray, edge1: float | FloatArray, x: FloatArray) -> FloatArray:
    t = np.clip((x - edge0) / (np.asarray(edge1) - edge0), 0.0, 1.0)
    return np.asarray(t * t * (3 - 2 * t), np.float64)


def soft_rect(
    s: FloatArray, t: FloatArray, s0: float, s1: float, t0: float, t1: float, blur: float
) -> FloatArray:
    """1 inside [s0, s1] x [t0, t1], 0 outside, with edges blurred over ``blur`` metres."""
    h = blur / 2
    return (
        smoothstep(s0 - h, s0 + h, s)
        * (1 - smoothstep(s1 - h, s1 + h, s))
        * smoothstep(t0 - h, t0 + h, t)
        * (1 - smoothstep(t1 - h, t1 + h, t))
    )


@dataclass(frozen=True)
class _Face:
    """A textured plane face: colours from (s, t) metres on it."""

    base: FloatArray
    waves: FloatArray  # (k, 5): ks, kt (rad/m), phase, amplitude, channel
    rects: list[tuple[float, float, float, float, FloatArray]]


def _random_face(
    rng: np.random.Generator,
    extent: tuple[float, float, float, float],
    n_rects: int,
    min_wavelength: float,
) -> _Face:
    base = rng.uniform(70, 190, 3)
    k = 9
    wl = rng.uniform(min_wavelength, 1.5, k)
    ang = rng.uniform(0, np.pi, k)
    kk = 2 * np.pi / wl
    waves = np.stack(
        [
            kk * np.cos(ang),
            kk * np.sin(ang),
            rng.uniform(0, 2 * np.pi, k),
            rng.uniform(5, 14, k),
            rng.integers(0, 3, k).astype(float),
        ],
        1,
    )
    s_lo, s_hi, t_lo, t_hi = extent
    rects = []
    for _ in range(n_rects):
        w, h = rng.uniform(0.25, 0.9), rng.uniform(0.2, 0.8)
        s0 = rng.uniform(s_lo, s_hi - w)
        t0 = rng.uniform(t_lo, t_hi - h)
        rects.append((s0, s0 + w, t0, t0 + h, rng.uniform(-90, 90, 3)))
    return _Face(base, waves, rects)


@dataclass(frozen=True)
class RoomScene:
    """A box room around the viewpoint, floor and walls textured, with one moving shape.

    Bounds (camera frame, metres): x in [x0, x1], y in [y0, y1], floor at
    z = -floor_depth, ceiling at z = ceiling_height. Faces: 0 x0-wall, 1 x1-wall,
    2 y0-wall, 3 y1-wall, 4 floor, 5 ceiling.
    """

    seed: int = 0
    x_range: tuple[float, float] = (-2.0, 2.4)
    y_range: tuple[float, float] = (-2.6, 2.2)
    floor_depth: float = 1.2
    ceiling_height: float = 1.6
    edge_blur: float = 0.05  # metres over which shape edges are blurred
    min_wavelength: float = 0.25  # metres, shortest texture wavelength
    mirror_center_world: tuple[float, float, float] = (0.3, -0.2, 1.2)
    _faces: list[_Face] = field(default_factory=list, repr=False, compare=False)

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.seed)
        (x0, x1), (y0, y1) = self.x_range, self.y_range
        zf, zc = -self.floor_depth, self.ceiling_height
        extents = [
            (y0, y1, zf, zc),
            (y0, y1, zf, zc),
            (x0, x1, zf, zc),
            (x0, x1, zf, zc),
            (x0, x1, y0, y1),
            (x0, x1, y0, y1),
        ]
        faces = [
            _random_face(rng, e, 3 if i < 4 else 2, self.min_wavelength)
            for i, e in enumerate(extents)
        ]
        self._faces.extend(faces)

    def intersect(
        self, origins: FloatArray, dirs: FloatArray
    ) -> tuple[FloatArray, NDArray[np.intp]]:
        """Distance to the first face hit from inside the box, and that face's index."""
        (x0, x1), (y0, y1) = self.x_range, self.y_range
        lo = np.array([x0, y0, -self.floor_depth])
        hi = np.array([x1, y1, self.ceiling_height])
        with np.errstate(divide="ignore", invalid="ignore"):
            t_hi = (hi - origins) / dirs
            t_lo = (lo - origins) / dirs
        t_axis = np.where(dirs > 0, t_hi, np.where(dirs < 0, t_lo, np.inf))
        axis = np.argmin(t_axis, axis=1)
        t = t_axis[np.arange(len(t_axis)), axis]
        positive = dirs[np.arange(len(dirs)), axis] > 0
        face = np.where(
            axis == 0,
            np.where(positive, 1, 0),
            np.where(axis == 1, np.where(positive, 3, 2), np.where(positive, 5, 4)),
        )
        return t, face.astype(np.intp)

    def _face_coords(self, p: FloatArray, face: NDArray[np.intp]) -> tuple[FloatArray, FloatArray]:
        s = np.where(face < 2, p[:, 1], p[:, 0])
        t = np.where(face < 4, p[:, 2], p[:, 1])
        return s, t

    def shade(self, origins: FloatArray, dirs: FloatArray, t: float = 0.0) -> FloatArray:
        """BGR colours in [0, 255] (float) of the first surface along each ray."""
        origins = np.broadcast_to(np.asarray(origins, np.float64), dirs.shape)
        dist, face = self.intersect(origins, dirs)
        p = origins + dist[:, None] * dirs
        s, tt = self._face_coords(p, face)
        out = np.empty((len(dirs), 3))
        for i, f in enumerate(self._faces):
            sel = face == i
            if not np.any(sel):
                continue
            out[sel] = self._texture(f, s[sel], tt[sel])
        sel = face == 4
        if np.any(sel):
            out[sel] -= 70 * self._floor_lines(s[sel], tt[sel])[:, None]
        sel = face < 4  # a dark skirting board along the walls' foot
        if np.any(sel):
            m = 1 - smoothstep(
                -self.floor_depth + 0.12, -self.floor_depth + 0.12 + self.edge_blur, tt[sel]
            )
            out[sel] = out[sel] * (1 - m[:, None]) + 50 * m[:, None]
        # a moving disc on the x1 wall (the video's change over time)
        sel = face == 1
        if np.any(sel):
            cs = -1.5 + 0.5 * t
            ct = -0.2 + 0.15 * np.sin(2.0 * t)
            d = np.hypot(s[sel] - cs, tt[sel] - ct)
            m = 1 - smoothstep(0.22 - self.edge_blur / 2, 0.22 + self.edge_blur / 2, d)
            out[sel] = out[sel] * (1 - m[:, None]) + np.array([30.0, 60.0, 220.0]) * m[:, None]
        bad = ~np.isfinite(dist)
        out[bad] = BACKGROUND
        return np.clip(out, 0, 255)

    def _texture(self, f: _Face, s: FloatArray, t: FloatArray) -> FloatArray:
        col = np.tile(f.base, (len(s), 1))
        for ks, kt, ph, amp, ch in f.waves:
            col[:, int(ch)] += amp * np.sin(ks * s + kt * t + ph)
        for s0, s1, t0, t1, dc in f.rects:
            m = soft_rect(s, t, s0, s1, t0, t1, self.edge_blur)
            col += m[:, None] * dc
        return col

    def _floor_lines(self, s: FloatArray, t: FloatArray) -> FloatArray:
        """0..1 darkness of floor-tile joints every 0.5 m, ~3 cm wide, edges blurred."""
        ds = np.abs(np.mod(s + 0.25, 0.5) - 0.25)
        dt = np.abs(np.mod(t + 0.25, 0.5) - 0.25)
        d = np.minimum(ds, dt)
        return 1 - smoothstep(0.015, 0.015 + self.edge_blur, d)
