"""Laser spot detection in a camera image of a screen: at most one spot per frame.

A laser spot saturates the camera sensor: a small white-ish core (every channel
high) with a rim of the laser's colour. Screen content can be as bright (white
areas, text) or as coloured (red and green details), so a spot must be all of:

1. new: its laser channel rises above a per-pixel background model of the screen
   by ``rise`` grey levels (static content does not fire). The model is the
   camera image itself, blended in by row bands (one band of ``bands`` per frame)
   and never where the spot is, so slowly changing content follows and a
   dwelling spot is not absorbed;
2. inside the calibrated screen region (``mask``);
3. saturated: the brightest pixel of the blob has every channel >= ``core``;
4. of the laser's colour: over the blob, the laser channel rose at least
   ``colour_ratio`` times as much as the strongest other channel;
5. small and round: ``min_area`` .. ``max_area`` full-resolution pixels,
   elongation (ratio of the principal axes) <= ``max_elongation``, fill (area
   over the area of the ellipse of its second moments) >= ``min_fill``.

A slide change (more than ``change_fraction`` of the screen changed at once)
makes the model useless for that frame: the frame is searched by appearance
only (tests 2-5 against a local background, the grey opening of a window around
each candidate, which removes anything smaller than the largest spot), and the
model restarts from the frame, with the spot's window filled by that opening.
The first frame is treated the same way.

Speed: candidates are found on every ``step``-th pixel of every ``step``-th row
(a spot is at least ``step * 1.5`` pixels across, so a sample lands in its
core); each candidate is then measured at full resolution in a small window.
``step=1`` is the straightforward reference path (every pixel is a candidate
pixel); both paths measure the same window, so they agree on the spot.

Coordinates: image pixels, u right, v down, the centre of the top-left pixel at
(0, 0). The position is the centroid of the laser channel's rise above the
background over the blob (sub-pixel).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

COLOURS = ("red", "green", "any")
LASER_CHANNEL = {"red": 2, "green": 1}  # BGR channel index of each laser colour


@dataclass(frozen=True, slots=True)
class LaserSpot:
    """One detected laser spot.

    Attributes:
        u, v: sub-pixel position in image pixels (centre of the top-left pixel = 0, 0).
        area: full-resolution pixels of the blob.
        peak: the largest laser-channel value in the blob (0..255).
        score: total rise of the laser channel over the background in the blob
            (grey levels x pixels); the best-scoring blob is the spot.
        colour: "red" or "green" (the laser channel the spot was found in).
    """

    u: float
    v: float
    area: int
    peak: int
    score: float
    colour: str


def auto_step(width: int) -> int:
    """The candidate sampling step for an image ``width`` pixels wide: 1 up to 799 px,
    2 up to 1199 px, then ``width // 400`` (a 6-screen-px spot on a screen filling a
    1280 px image is about 6 image px across)."""
    if width < 800:
        return 1
    return max(2, width // 400)


_EDGE = 10.0  # grey levels: the soft edge of the spot's light for its centroid
_CLIP_RISE = 12  # grey levels a clipped pixel must have risen to be a candidate
_STALE = LaserSpot(math.nan, math.nan, 0, 0, 0.0, "stale")  # marker: measure by appearance


class SpotDetector:
    """Finds the laser spot in successive BGR frames of one camera (see the module
    docstring). Keep one detector per camera: it carries the background model.

    Args:
        colour: the laser's colour, "red", "green" or "any" (either).
        mask: H x W bool, True on the calibrated screen region; None: the whole image.
        step: candidate sampling step in pixels (None: :func:`auto_step`; 1: reference path).
        rise: grey levels the laser channel must rise above the background.
        core: grey level every channel must reach at the blob's brightest pixel.
        colour_ratio: laser-channel rise over the rise of the strongest other channel.
        min_area, max_area: blob size limits, full-resolution pixels.
        max_elongation: largest ratio of the blob's principal axes.
        min_fill: smallest blob area over its moment ellipse's area.
        change_fraction: fraction of the screen (sampled) changing by ``rise`` at
            once that counts as a slide change.
        bands: the background is refreshed one row band of ``bands`` per frame.
    """

    def __init__(
        self,
        colour: str = "red",
        mask: NDArray[np.bool_] | None = None,
        *,
        step: int | None = None,
        rise: int = 40,
        core: int = 200,
        saturated: int = 250,
        halo: float = 5.0,
        colour_ratio: float = 1.15,
        min_area: int = 3,
        max_area: int = 600,
        max_elongation: float = 2.5,
        min_fill: float = 0.55,
        change_fraction: float = 0.03,
        bands: int = 8,
    ) -> None:
        if colour not in COLOURS:
            raise ValueError(f"colour must be one of {', '.join(COLOURS)}, got {colour!r}")
        if step is not None and step < 1:
            raise ValueError(f"step must be >= 1 pixel, got {step}")
        if not 0 < rise < 255 or not 0 < core <= 255:
            raise ValueError(f"rise and core must be grey levels 1..254, got {rise}, {core}")
        if not 1 <= min_area <= max_area:
            raise ValueError(f"need 1 <= min_area <= max_area, got {min_area}, {max_area}")
        if max_elongation < 1.0 or not 0.0 <= min_fill <= 1.0 or colour_ratio <= 0:
            raise ValueError("need max_elongation >= 1, 0 <= min_fill <= 1, colour_ratio > 0")
        if not 0 < change_fraction <= 1 or bands < 1:
            raise ValueError("need 0 < change_fraction <= 1 and bands >= 1")
        self.colour = colour
        self.channels = (2, 1) if colour == "any" else (LASER_CHANNEL[colour],)
        self.mask = None if mask is None else np.ascontiguousarray(mask, dtype=bool)
        self.step = step
        self.rise = rise
        self.core = core
        self.saturated = saturated
        self.halo = halo
        self._ring_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
        self._grow_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
        self._mid_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9))
        self._far_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (17, 17))
        self._stale = np.zeros((0, 0), bool)  # H x W: model pixels whose content is a guess
        self._stale_boxes: list[tuple[int, int, int, int]] = []  # windows holding them
        self.colour_ratio = colour_ratio
        self.min_area = min_area
        self.max_area = max_area
        self.max_elongation = max_elongation
        self.min_fill = min_fill
        self.change_fraction = change_fraction
        self.bands = bands
        r = math.sqrt(max_area / math.pi)
        self.half = math.ceil(r) + 3  # refinement window half size, px
        self.open_kernel = cv2.getStructuringElement(
            cv2.MORPH_RECT, (2 * math.ceil(r) + 3, 2 * math.ceil(r) + 3)
        )
        self.background: NDArray[np.uint8] | None = None
        self.slide_changes = 0  # frames treated as a slide change (for figures)
        self._frame = 0
        self._k = 1
        self._mask_lo: NDArray[np.bool_] | None = None
        self._mask_count = 1

    def reset(self) -> None:
        """Forget the background model (the next frame is searched by appearance)."""
        self.background = None
        self._frame = 0

    # -- per frame -------------------------------------------------------------------

    def detect(self, image: NDArray[np.uint8]) -> LaserSpot | None:
        """The laser spot in a BGR H x W x 3 uint8 frame, or None; updates the model."""
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"need an H x W x 3 uint8 BGR image, got {image.dtype} {image.shape}")
        h, w = image.shape[:2]
        if self.mask is not None and self.mask.shape != (h, w):
            raise ValueError(f"mask is {self.mask.shape[1]}x{self.mask.shape[0]}, image {w}x{h}")
        bg = self.background
        if bg is None or bg.shape != image.shape:
            self._start(w)
            return self._restart(image)
        k = self._k
        lo = image[::k, ::k]
        bg_lo = bg[::k, ::k]
        rise_lo: NDArray[np.int16] | None = None
        for c in self.channels:
            d = lo[:, :, c].astype(np.int16) - bg_lo[:, :, c]
            rise_lo = d if rise_lo is None else np.maximum(rise_lo, d)
        assert rise_lo is not None
        changed = np.abs(rise_lo) >= self.rise
        if self._mask_lo is not None:
            changed &= self._mask_lo
        if not self._mask_count:
            self._mask_count = changed.size
        if np.count_nonzero(changed) > self.change_fraction * self._mask_count:
            self.slide_changes += 1
            return self._restart(image)
        bright = lo[:, :, self.channels[0]]
        if len(self.channels) == 2:
            bright = np.maximum(bright, lo[:, :, self.channels[1]])
        # a spot's pixels rose by ``rise``, or clipped (on bright content, where the
        # laser channel cannot rise that far)
        cand = ((rise_lo >= self.rise) | ((bright >= self.saturated) & (rise_lo >= _CLIP_RISE))) & (
            bright >= self.core
        )
        if self._mask_lo is not None:
            cand &= self._mask_lo
        spot, _ = self._best(image, cand, bg)
        if spot is None:  # a spot the model absorbed (missed before): by appearance
            spot, seeds = self._best(image, self._saturated(lo), None)
            self._repair(image, seeds)
        else:
            self._refresh(image, spot)
        self._update(image, spot)
        return spot

    # -- steps -----------------------------------------------------------------------

    def _start(self, width: int) -> None:
        self._k = self.step if self.step is not None else auto_step(width)
        k = self._k
        if self.mask is not None:
            self._mask_lo = np.ascontiguousarray(self.mask[::k, ::k])
            self._mask_count = max(1, int(np.count_nonzero(self._mask_lo)))
        else:
            self._mask_lo = None
            self._mask_count = 0  # set from the first frame's sample grid
        self._frame = 0

    def _saturated(self, lo: NDArray[np.uint8]) -> NDArray[np.bool_]:
        """Sample pixels that can be a spot's core: laser channel clipped, all channels high."""
        cand: NDArray[np.bool_] = (
            np.minimum(np.minimum(lo[:, :, 0], lo[:, :, 1]), lo[:, :, 2]) >= self.core
        )
        bright = lo[:, :, self.channels[0]]
        if len(self.channels) == 2:
            bright = np.maximum(bright, lo[:, :, self.channels[1]])
        cand &= bright >= self.saturated
        if self._mask_lo is not None:
            cand &= self._mask_lo
        return cand

    def _repair(self, image: NDArray[np.uint8], seeds: list[tuple[int, int]]) -> None:
        """Take small bright blobs at ``seeds`` (full-res u, v) out of the model.

        In each seed's window, the blob's footprint (where a laser channel stands
        ``rise / 2`` above the grey opening of the frame, grown by 2 px) gets the
        opening's values, a guess of the content under it; the footprint is
        marked stale and gets the frame's true values as soon as no spot covers
        it (:meth:`_refresh`).
        """
        bg = self.background
        assert bg is not None
        h, w = image.shape[:2]
        for su, sv in seeds:
            v0, v1, u0, u1 = self._window(float(su), float(sv), h, w)
            win = image[v0:v1, u0:u1]
            opened = cv2.morphologyEx(win, cv2.MORPH_OPEN, self.open_kernel)
            foot = np.zeros(win.shape[:2], np.uint8)
            for c in self.channels:
                foot |= cv2.subtract(win[:, :, c], opened[:, :, c]) >= self.rise // 2
            grown = cv2.dilate(foot, self._grow_kernel).view(bool)
            bg[v0:v1, u0:u1][grown] = opened[grown]
            self._stale[v0:v1, u0:u1] |= grown
            self._stale_boxes.append((v0, v1, u0, u1))

    def _stale_in(self, v0: int, v1: int, u0: int, u1: int) -> NDArray[np.bool_] | None:
        """The stale model pixels of window rows v0:v1, columns u0:u1 (None: none)."""
        for a0, a1, b0, b1 in self._stale_boxes:
            if a0 < v1 and v0 < a1 and b0 < u1 and u0 < b1:
                sub = self._stale[v0:v1, u0:u1]
                return sub if sub.any() else None
        return None

    def _refresh(self, image: NDArray[np.uint8], spot: LaserSpot | None) -> None:
        """Stale model pixels the spot does not cover now get the frame's values.

        The spot covers a disc of its blob's radius + 3 px around its centre.
        """
        if not self._stale_boxes:
            return
        bg = self.background
        assert bg is not None
        keep = []
        for v0, v1, u0, u1 in self._stale_boxes:
            sub = self._stale[v0:v1, u0:u1]
            free = sub.copy()
            if spot is not None:
                r = math.sqrt(spot.area / math.pi) + 3.0
                yy, xx = np.ogrid[v0:v1, u0:u1]
                free &= (xx - spot.u) ** 2 + (yy - spot.v) ** 2 > r * r
            bg[v0:v1, u0:u1][free] = image[v0:v1, u0:u1][free]
            sub[free] = False
            if sub.any():
                keep.append((v0, v1, u0, u1))
        self._stale_boxes = keep

    def _restart(self, image: NDArray[np.uint8]) -> LaserSpot | None:
        """Appearance-only search; the model restarts from ``image`` without spot-like blobs."""
        k = self._k
        spot, seeds = self._best(image, self._saturated(image[::k, ::k]), None)
        self.background = image.copy()
        self._stale = np.zeros(image.shape[:2], bool)
        self._stale_boxes = []
        self._repair(image, seeds)
        self._frame = 0
        return spot

    def _update(self, image: NDArray[np.uint8], spot: LaserSpot | None) -> None:
        """Blend one row band of the frame into the model, except the spot's window."""
        bg = self.background
        assert bg is not None
        h = image.shape[0]
        band = (h + self.bands - 1) // self.bands
        b0 = (self._frame % self.bands) * band
        b1 = min(h, b0 + band)
        self._frame += 1
        if b0 >= b1:
            return
        keep = None
        if spot is not None:
            win = self._window(spot.u, spot.v, h, image.shape[1])
            keep = (win, bg[win[0] : win[1], win[2] : win[3]].copy())
        cv2.addWeighted(image[b0:b1], 0.5, bg[b0:b1], 0.5, 0.0, dst=bg[b0:b1])
        if keep is not None:
            (v0, v1, u0, u1), saved = keep
            bg[v0:v1, u0:u1] = saved

    def _window(self, u: float, v: float, h: int, w: int) -> tuple[int, int, int, int]:
        """Rows v0:v1 and columns u0:u1 of the refinement window around (u, v)."""
        r = self.half + self._k
        cu, cv_ = round(u), round(v)
        return max(0, cv_ - r), min(h, cv_ + r + 1), max(0, cu - r), min(w, cu + r + 1)

    def _best(
        self,
        image: NDArray[np.uint8],
        cand: NDArray[np.bool_],
        bg: NDArray[np.uint8] | None,
    ) -> tuple[LaserSpot | None, list[tuple[int, int]]]:
        """The best spot among candidate sample pixels (``bg`` None: appearance only), and
        the full-res pixels (u, v) of the candidate groups measured."""
        rows = np.flatnonzero(cand.any(axis=1))
        if rows.size == 0:
            return None, []
        cols = np.flatnonzero(cand[rows[0] : rows[-1] + 1].any(axis=0))
        r0, c0 = int(rows[0]), int(cols[0])  # label only the box holding candidates
        box = cand[r0 : int(rows[-1]) + 1, c0 : int(cols[-1]) + 1]
        _, labels, stats, _ = cv2.connectedComponentsWithStats(
            np.ascontiguousarray(box).view(np.uint8), connectivity=8
        )
        stats[:, cv2.CC_STAT_LEFT] += c0
        stats[:, cv2.CC_STAT_TOP] += r0
        k = self._k
        h, w = image.shape[:2]
        limit = self.max_area / (k * k) + 4 * (self.max_area**0.5 / k + 1)
        best: LaserSpot | None = None
        # the largest candidate groups first; too large to be a spot: skipped here
        order = np.argsort(-stats[1:, cv2.CC_STAT_AREA]) + 1
        seeds: list[tuple[int, int]] = []
        for lab in order:
            if stats[lab, cv2.CC_STAT_AREA] > limit:
                continue
            x0, y0 = stats[lab, cv2.CC_STAT_LEFT], stats[lab, cv2.CC_STAT_TOP]
            bw, bh = stats[lab, cv2.CC_STAT_WIDTH], stats[lab, cv2.CC_STAT_HEIGHT]
            ys, xs = np.nonzero(labels[y0 - r0 : y0 - r0 + bh, x0 - c0 : x0 - c0 + bw] == lab)
            su, sv = (x0 + xs[0]) * k, (y0 + ys[0]) * k  # a full-res core pixel of the group
            spot = self._measure(image, bg, su, sv, h, w)
            seeds.append((int(su), int(sv)))
            if spot is not None and (best is None or spot.score > best.score):
                best = spot
            if len(seeds) >= 32:  # a frame of many saturated specks: the largest are enough
                break
        return best, seeds

    def _measure(
        self,
        image: NDArray[np.uint8],
        bg: NDArray[np.uint8] | None,
        su: int,
        sv: int,
        h: int,
        w: int,
    ) -> LaserSpot | None:
        """Measure the blob through full-res pixel (su, sv) in a window; None if no spot.

        With a background model (``bg``): the blob is where the laser channel rose
        by ``rise / 2`` or more. Without (first frame, slide change), or where the
        model is stale (a spot was taken out of it and the content under it is
        not known yet): the blob is the laser channel's saturated core, and the
        halo around it must be of the laser's colour.
        """
        v0, v1, u0, u1 = self._window(float(su), float(sv), h, w)
        win = image[v0:v1, u0:u1]
        best: LaserSpot | None = None
        stale = None if bg is None else self._stale_in(v0, v1, u0, u1)
        for c in self.channels:
            spot = None
            if bg is not None:
                spot = self._measure_rise(win, bg[v0:v1, u0:u1], c, su - u0, sv - v0, stale)
            if bg is None or spot is _STALE:
                spot = self._measure_core(win, c, su - u0, sv - v0)
            if spot is not None and (best is None or spot.score > best.score):
                best = spot
        if best is None:
            return None
        return LaserSpot(best.u + u0, best.v + v0, best.area, best.peak, best.score, best.colour)

    def _blob(self, binary: NDArray[np.bool_], su: int, sv: int) -> NDArray[np.bool_] | None:
        """The connected blob of ``binary`` through (su, sv) if its size and shape fit."""
        _, lab = cv2.connectedComponents(binary.view(np.uint8), connectivity=8)
        sel: NDArray[np.bool_] = lab == lab[sv, su]
        ys, xs = np.nonzero(sel)
        area = int(ys.size)
        if not self.min_area <= area <= self.max_area:
            return None
        wh, ww = binary.shape
        if ys.min() == 0 or xs.min() == 0 or ys.max() == wh - 1 or xs.max() == ww - 1:
            return None  # runs out of the window: larger than a spot
        xm, ym = xs.mean(), ys.mean()
        cxx = float(((xs - xm) ** 2).mean()) + 1 / 12  # + a pixel's own spread
        cyy = float(((ys - ym) ** 2).mean()) + 1 / 12
        cxy = float(((xs - xm) * (ys - ym)).mean())
        tr, det = cxx + cyy, cxx * cyy - cxy * cxy
        disc = math.sqrt(max(0.0, tr * tr / 4 - det))
        l1, l2 = tr / 2 + disc, max(tr / 2 - disc, 1e-9)
        if math.sqrt(l1 / l2) > self.max_elongation:
            return None
        if area / (4 * math.pi * math.sqrt(l1 * l2)) < self.min_fill:
            return None
        return sel

    def _spot(
        self, win: NDArray[np.uint8], sel: NDArray[np.bool_], wgt: NDArray[np.float64], c: int
    ) -> LaserSpot:
        """The weighted centroid of blob ``sel`` (window pixels)."""
        ys, xs = np.nonzero(sel)
        tot = float(wgt.sum())
        u = float((wgt * xs).sum()) / tot
        v = float((wgt * ys).sum()) / tot
        peak = int(win[:, :, c][sel].max())
        return LaserSpot(u, v, int(ys.size), peak, tot, "red" if c == 2 else "green")

    def _measure_rise(
        self,
        win: NDArray[np.uint8],
        ref: NDArray[np.uint8],
        c: int,
        su: int,
        sv: int,
        stale: NDArray[np.bool_] | None,
    ) -> LaserSpot | None:
        """The blob of the laser channel's rise over the model; :data:`_STALE` when the blob
        or its halo touches stale model pixels (measure by appearance instead)."""
        d = win.astype(np.int16) - ref.astype(np.int16)  # rise of each channel
        dl = d[:, :, c]
        if stale is not None and stale[sv, su]:
            return _STALE
        if dl[sv, su] < self.rise and not (
            win[sv, su, c] >= self.saturated and dl[sv, su] >= _CLIP_RISE
        ):
            return None
        sel = self._blob(dl >= self.rise // 2, su, sv)
        if sel is None:
            return _STALE if stale is not None else None
        if (
            stale is not None
            and (cv2.dilate(sel.view(np.uint8), self._ring_kernel).view(bool) & stale).any()
        ):
            return _STALE
        if not self._coloured(win, d, sel, c):
            return None
        # a clipped laser channel and a white-ish core
        if int(win[:, :, c][sel].max()) < self.saturated:
            return None
        if int(win[sel].min(axis=1).max()) < self.core:
            return None
        # centroid of the spot's own light: a soft disc where the laser channel rose by
        # _EDGE .. 2 _EDGE (its edge lies in the halo, which is not clipped, so bright
        # or dark content under the spot does not move it); clipped pixels weigh 1
        soft = np.clip((dl.astype(np.float64) - _EDGE) / _EDGE, 0.0, 1.0)
        region = cv2.dilate(sel.view(np.uint8), self._grow_kernel).view(bool) & (soft > 0)
        return self._spot(win, region, soft[region], c)

    def _coloured(
        self, win: NDArray[np.uint8], d: NDArray[np.int16], sel: NDArray[np.bool_], c: int
    ) -> bool:
        """Whether the light added around blob ``sel`` is of the laser's colour.

        Over the halo (the blob grown by 3 px, where the laser channel is not
        clipped), the laser channel must have risen at least ``colour_ratio``
        times as much as the strongest other channel, each rise counted as a
        fraction of the room its channel had below 255 (on content of the
        laser's own colour the laser channel has little room left). Clipped
        pixels say nothing about colour: a spot's core is white, and on bright
        content its halo clips the laser channel too.
        """
        grown = cv2.dilate(sel.view(np.uint8), self._ring_kernel).view(bool)
        halo = grown & (win[:, :, c] < self.saturated)
        if not halo.any():
            return False
        dh = d[halo].astype(np.float64)  # (n, 3) rise of each channel
        room = 256.0 - (win[halo].astype(np.float64) - dh)  # 256 - the model's level
        rel = dh.clip(0.0) / room
        others = [o for o in (0, 1, 2) if o != c]
        rise_c = float(rel[:, c].sum())
        rise_o = float(np.maximum(rel[:, others[0]], rel[:, others[1]]).sum())
        return rise_c > 0 and rise_c >= self.colour_ratio * rise_o

    def _halo_coloured(self, win: NDArray[np.uint8], sel: NDArray[np.bool_], c: int) -> bool:
        """Whether a clipped core ``sel`` has a halo of the laser's colour, judged without a
        background: the laser channel's excess over the strongest other channel is
        larger 1-2 px outside the core (upper quartile) than 5-8 px outside it
        (median: the content's own colour), by ``halo`` grey levels."""
        blob = sel.view(np.uint8)
        near = cv2.dilate(blob, self._grow_kernel).view(bool)
        far = cv2.dilate(blob, self._far_kernel).view(bool)
        inner = near & ~sel & (win[:, :, c] < self.saturated)
        outer = far & ~cv2.dilate(blob, self._mid_kernel).view(bool)
        if not inner.any() or not outer.any():
            return False
        wi = win.astype(np.int16)
        others = [o for o in (0, 1, 2) if o != c]
        excess = wi[:, :, c] - np.maximum(wi[:, :, others[0]], wi[:, :, others[1]])
        gain = float(np.percentile(excess[inner], 75)) - float(np.median(excess[outer]))
        return gain >= self.halo

    def _measure_core(self, win: NDArray[np.uint8], c: int, su: int, sv: int) -> LaserSpot | None:
        lc = win[:, :, c]
        if lc[sv, su] < self.saturated:
            return None
        sel = self._blob(lc >= self.saturated, su, sv)
        if sel is None:
            return None
        if int(win[sel].min(axis=1).max()) < self.core:
            return None
        if not self._halo_coloured(win, sel, c):
            return None
        wgt = np.ones(int(np.count_nonzero(sel)))  # the clipped core's own centre
        return self._spot(win, sel, wgt, c)
