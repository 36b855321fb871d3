"""Laser spot detection without a white core: the laser channel's clipped blob, new
against a model of the displayed content, of the laser's colour against the content
around it. At most one spot per frame; no spot rather than a guess.

A webcam watching a red laser spot often clips only the red channel: red 255,
green and blue 90-230 at the brightest pixel (a white core appears only when the
laser is bright enough to clip the other channels through the sensor's colour
crosstalk). Screen content can be as bright and as coloured: white and yellow
pages clip every channel or red and green together, red text and icons clip red.
So a spot must be all of:

1. **clipped**: its laser channel reaches ``saturated`` over a blob;
2. **small and compact**: ``min_area`` .. ``max_area`` full-resolution pixels,
   principal-axis ratio <= ``max_elongation`` (a spot smeared by its motion within
   the exposure is a short streak), fill >= ``min_fill``;
3. **of the laser's colour**: the ring 1-3 px outside the blob is more of the
   laser's colour (laser channel minus the strongest other channel) than the
   content 5-9 px outside, by ``halo`` grey levels, and brighter in the laser
   channel by ``halo`` (a clipped white or yellow patch has no such ring; a spot
   on a white page has one, its laser channel clipping where the others do not);
4. **new**: at least ``min_new`` of its pixels were not clipped in the model of
   the displayed content (static red text and icons, however bright, never fire),
   and the blob with the 2 px around it rose over the model by ``min_rise`` grey
   levels on average (a beam lifts its whole disc; noise crossing the clipping level
   on a bright page does not). Over content already within ``new_margin`` of
   clipping in the laser channel (a bright page of the laser's colour) the laser
   channel has no room to rise: there a clipped blob is new where the other
   channels rose over the model by ``bright_rise`` (the laser's light leaking into
   them), and ``min_rise`` asks that of them;
5. **as bright as the camera goes**: its laser-channel peak within ``peak_margin``
   of the highest level the laser channel has shown on the screen so far (a beam
   drives its channel to the top; content just crossing ``saturated`` does not);
6. **inside the screen** (``mask``, from the calibration).

The content model is the camera image itself, refreshed one row band of ``bands``
per frame, except where the laser channel newly clipped (a spot never enters it);
where the frame is darker than the model by ``rise`` (a laser only adds light) the
model is out of date and takes the frame once the frame has been searched, except
(``hold_spot``) the pixels of this and the last spot's window where the laser channel
rose (content changing beside a spot would otherwise copy the spot into the model,
and it would be lost). The search comes first because a codec's chroma bleed darkens
the other channels around a spot that has just appeared, and the fix's reach (the
sampled pixels' neighbourhood) would take part of the spot into the model: it was then
placed from the rest of it, up to 1 image px off (tuning scenes 1021, 1078).

Where the model cannot tell static from new, a blob is taken only within
``track_px`` of the previous frame's spot:

- a **slide change** (more than ``change_fraction`` of the screen changed by
  ``rise``): the model restarts from the frame, without the spot's footprint;
- **busy** regions, where content got darker in two of the last 16 frames
  (videos, animations, moving windows), for ``busy_frames`` frames.

The first frame only starts the model (a spot shows as soon as it moves). When two
blobs far apart both pass and the weaker scores at least half the stronger, the
frame has no spot (refused).

Speed: the laser channel is tested at full resolution with a handful of OpenCV
calls; the slide-change and busy tests use every ``step``-th pixel (automatic:
4); each candidate blob is measured in a small window.

Coordinates: image pixels, u right, v down, the centre of the top-left pixel at
(0, 0). The position (``position`` "beam", the default) is the centre of a round
Gaussian fitted to the laser channel's rise over the model in linear light, with
clipped pixels censored (they say only that the beam filled the room the content
left below clipping), so the content under the spot does not bend it; with
``beam_channels`` 3 (the default) the other two channels' rise (the laser's light
leaking into them, rarely clipped) is fitted too, each channel with its own amplitude,
width and offset about the one centre; "centroid" is
the clipped blob's centroid with a soft edge (pixels ``soft`` grey levels below
``saturated`` weigh 0, clipped ones 1), also the fallback where the fit fails.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.laser.spot import COLOURS, LASER_CHANNEL, LaserSpot

_BLOCK = 16  # full-resolution px: the busy map's block size
# grey levels below ``saturated`` the model must be for a pixel to be new (default of
# ``new_margin``). With 2026-12-02's tests, 30 (tuning 1000-1039: 51.2 %, 34 false;
# held-out 600000-600041: 49.1 %, 48 false) beat 20 (53.7 %, 31; 50.7 %, 79). With
# min_rise, fringe_ratio and peak_margin (2026-12-05), 20 found 1350 of 2029 spot frames
# with 77 false spots on 2423 spot-off frames (tuning 1000-1159), 30 1277 with 76.
_NEW_MARGIN = 20
_POPCOUNT = np.array([bin(i).count("1") for i in range(256)], np.uint8)
_LIN = (np.arange(256) / 255.0) ** 2.2  # grey level -> linear light (gamma 2.2)


def _sample(img: NDArray[np.uint8], k: int) -> NDArray[np.uint8]:
    """``img[::k, ::k]``, contiguous (OpenCV's nearest-neighbour resize picks exactly
    those pixels at an integer scale, several times faster than numpy's strided copy)."""
    if k == 1:
        return img
    h, w = img.shape[:2]
    hk, wk = h // k, w // k
    if hk == 0 or wk == 0:
        return np.ascontiguousarray(img[::k, ::k])
    out: NDArray[np.uint8] = np.asarray(
        cv2.resize(img[: hk * k, : wk * k], (wk, hk), interpolation=cv2.INTER_NEAREST), np.uint8
    )
    if out.ndim < img.ndim:
        out = out[..., None]
    if wk * k < w:  # the last sampled column lies in the remainder
        out = np.concatenate([out, img[: hk * k : k, wk * k : wk * k + 1]], axis=1)
    if hk * k < h:
        out = np.concatenate([out, img[hk * k : hk * k + 1, ::k]], axis=0)
    return out


def _upper_mean(x: NDArray[Any]) -> float:
    """The mean of the upper half of integer values ``x`` (its sorted ``x[n // 2:]``)."""
    n = x.size
    part = np.partition(x, n // 2)[n // 2 :]
    return int(part.sum(dtype=np.int64)) / part.size


def _median(x: NDArray[Any]) -> float:
    """The median of integer values ``x`` (as ``np.median``, without its overhead)."""
    n = x.size
    if n % 2:
        return float(np.partition(x, n // 2)[n // 2])
    part = np.partition(x, (n // 2 - 1, n // 2))
    return (int(part[n // 2 - 1]) + int(part[n // 2])) / 2


_LAYOUTS: dict[int, tuple[Any, ...]] = {}


def _layout(k: int) -> tuple[Any, ...]:
    """The parameter layout of :func:`_fit_beams` for ``k`` channels (cached): p, the
    lower and upper bounds (the upper width bounds set per fit), the indices of each
    channel's ln A, ln s and b, and where each channel's 5 x 5 block of J^T J (and its
    5 entries of J^T r) are summed into the p x p matrix (the p vector)."""
    if k not in _LAYOUTS:
        p = 2 + 3 * k
        lo = np.full(p, -np.inf)
        hi = np.full(p, np.inf)
        lo[2:] = np.tile((math.log(1e-3), math.log(0.3), -0.5), k)
        hi[2::3], hi[4::3] = math.log(100.0), 0.5
        chan = np.arange(k)
        ca, cs, cb = 2 + 3 * chan, 3 + 3 * chan, 4 + 3 * chan
        cols = np.stack([np.zeros(k, np.int64), np.ones(k, np.int64), ca, cs, cb], axis=1)
        h_at = (cols[:, :, None] * p + cols[:, None, :]).ravel()
        parts = (lo, hi, ca, cs, cb, h_at, cols.ravel(), np.arange(p) * (p + 1))
        for a in parts:
            a.setflags(write=False)  # shared by every fit: copied where a fit changes one
        _LAYOUTS[k] = (p, *parts)
    return _LAYOUTS[k]


def _fit_beams(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    obs: NDArray[np.float64],
    room: NDArray[np.float64],
    cens: NDArray[np.bool_],
    start: NDArray[np.float64],
    iterations: int = 30,
) -> tuple[float, float] | None:
    """Levenberg-Marquardt fit of one round Gaussian beam seen in K channels: channel k's
    rise ``obs[k]`` (linear light) at pixels (x, y) is ``b_k + A_k exp(-d^2 / 2 s_k^2)``
    about the shared centre (a codec blurs colour planes differently); where ``cens[k]``
    (the channel clipped) the rise is only known to be >= ``room[k]``. ``obs``, ``room``,
    ``cens`` are K x N. Parameters (u, v, then ln A_k, ln s_k, b_k per channel) from
    ``start``, kept inside bounds (A 1e-3..100, s 0.3 px .. 4 x its start + 8 px,
    |b| <= 0.5); stops when the centre moves less than 0.05 px. Returns the centre
    (u, v) of the best fit found, or None if the normal equations are singular."""
    k, n = obs.shape
    p, lo, hi0, ca, cs, cb, h_at, g_at, diag = _layout(k)
    hi = hi0.copy()
    hi[3::3] = np.log(4 * np.exp(start[3::3]) + 8)
    # channel j's Jacobian has 5 non-zero columns (u, v, its A, s, b): K x 5 x N
    jac = np.empty((k, 5, n))
    jac[:, 4] = 1.0
    any_c = bool(cens.any())

    def normal(
        t: NDArray[np.float64],
    ) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
        """The cost, J^T J and J^T r at parameters ``t``."""
        dx, dy = x - t[0], y - t[1]
        d2 = dx * dx + dy * dy
        inv = np.exp(-2.0 * t[cs])
        g = np.exp(np.multiply.outer(-0.5 * inv, d2) + t[ca][:, None])
        pred = g + t[cb][:, None]
        gi = g * inv[:, None]
        np.multiply(gi, dx, out=jac[:, 0])
        np.multiply(gi, dy, out=jac[:, 1])
        jac[:, 2] = g
        np.multiply(gi, d2, out=jac[:, 3])
        res = obs - pred
        over = None
        if any_c:  # censored: no residual once the beam fills the room, else the shortfall
            over = cens & (pred >= room)
            res = np.where(cens, np.where(over, 0.0, room - pred), res)
            if over.any():
                np.multiply(jac, ~over[:, None, :], out=jac)
            else:
                over = None
        hb = jac @ jac.transpose(0, 2, 1)
        gb = jac @ res[:, :, None]
        if over is not None:
            jac[:, 4] = 1.0
        h = np.asarray(np.bincount(h_at, hb.ravel(), p * p), np.float64).reshape(p, p)
        grad = np.asarray(np.bincount(g_at, gb.ravel(), p), np.float64)
        return float(np.vdot(res, res)), h, grad

    th = np.clip(start, lo, hi)
    cost, h, grad = normal(th)
    lam = 1e-3
    for _ in range(iterations):
        a = h.copy()
        a.flat[diag] += lam * (a.flat[diag] + 1e-9)
        try:
            step = np.linalg.solve(a, grad)
        except np.linalg.LinAlgError:
            return None
        cand = th + step
        if np.all((cand >= lo) & (cand <= hi) & np.isfinite(cand)):
            c2, h2, g2 = normal(cand)
            if c2 < cost:
                th, cost, h, grad, lam = cand, c2, h2, g2, lam * 0.3
                if abs(step[0]) < 0.05 and abs(step[1]) < 0.05:
                    break
                continue
        lam *= 10.0
        if lam > 1e6:
            break
    return float(th[0]), float(th[1])


class ColourSpotDetector:
    """Finds the laser spot in successive BGR frames of one camera (module docstring).

    Keep one detector per camera: it carries the content model.

    Args:
        colour: "red", "green" or "any".
        mask: H x W bool, True on the screen region; None: the whole image.
        step: sampling step of the slide-change and busy tests, px (1: every pixel).
        saturated: the laser channel's level where it clips, grey levels.
        soft: grey levels below ``saturated`` where the centroid's weights start.
        rise: grey levels of change that count (slide change, darker content).
        halo: grey levels of colour excess and laser-channel brightness the ring
            must have over the content around it.
        colour_ratio: with the model: the laser channel's rise over the strongest other
            channel's (fractions of their room below 255), the colour test on content
            of the laser's own colour, where the ring test cannot see the spot.
        fringe: largest fraction of the blob where the other channels clip too (a
            white-cored spot's clipped laser channel reaches beyond its white core).
        min_new: fraction of the blob's pixels that must be new.
        min_area, max_area: blob size limits, full-resolution px.
        max_elongation: largest principal-axis ratio (motion streaks).
        min_fill: smallest blob area over its moment ellipse's area.
        change_fraction: fraction of the screen changing at once that is a slide change.
        busy_frames: frames a region stays busy.
        track_px: how far (px) from the previous spot a blob may be where the model
            cannot tell.
        busy_gain: in busy regions, the ring gain (grey levels) a blob far from the
            previous spot needs.
        bands: the model is refreshed one row band of ``bands`` per frame.
        max_darker: with the model: the largest fraction of the blob and the 3 px around
            it where some channel got darker than the model by ``rise`` (a laser only
            adds light; content of the laser's colour moving in replaces what was there).
        min_cross: with the model: the smallest rise of the strongest other channel over
            the model, linear light (0..1), on the upper half of the blob (a laser's light
            leaks into every channel; content of its colour raises only its own). 0: off.
        busy_events: frames of the last 16 with darker content that make a block busy.
        new_margin: grey levels below ``saturated`` the model's laser channel must be
            for a clipped pixel to be new.
        confirm: frames in a row a spot must be found (each within ``track_px`` of the
            one before) before it is reported (1: at once).
        busy_confirm: as ``confirm``, for a track that starts in a busy region (content
            moving there: videos, animations); the larger of the two applies there
            (tuning scenes 600000-600041: 2 cut false spots 47 -> 38 of 604 spot-off
            frames at the same 250 of 511 hits; 1: off).
        position: "beam" (the censored Gaussian fit of the module docstring),
            "centroid" (the soft-edged centroid of the clipped blob) or "fit" (a
            log-quadratic fit to the rise on the unclipped pixels around the blob); the
            centroid where a fit fails.
        min_rise: with the model: the smallest mean rise (grey levels) of the laser
            channel over the blob and the 2 px around it. 0: off.
        fringe_ratio: with the model: a blob accepted by its fringe also needs the
            halo's rise ratio (as ``colour_ratio``) of at least this (white look-alikes
            that do not clip every channel). 0: off.
        hold_spot: the last spot's window keeps its model where the laser channel rose
            when darker content nearby refreshes the model.
        peak_margin: grey levels the blob's laser-channel peak may lie below the
            highest level seen on the screen (255: off).
        beam_channels: channels the "beam" position fits: 3 (the laser channel and the
            two others, about one centre) or 1 (the laser channel alone).
        bright_rise: with the model: over content whose laser channel was already within
            ``new_margin`` of clipping (a bright page of the laser's colour, where the
            spot cannot rise in its own channel), a clipped blob is new where the
            strongest other channel rose over the model by this many grey levels on
            ``min_new`` of it, and ``min_rise`` then asks its rise of the others. 0: off
            (such a spot is never found).
        search_first: the frame is searched before the model takes its darker pixels
            (module docstring); False: after, as before 2026-12-06.
    """

    def __init__(
        self,
        colour: str = "red",
        mask: NDArray[np.bool_] | None = None,
        *,
        step: int = 4,
        saturated: int = 245,
        soft: int = 40,
        rise: int = 30,
        halo: float = 20.0,
        colour_ratio: float = 1.15,
        fringe: float = 0.6,
        min_new: float = 0.1,
        min_area: int = 2,
        max_area: int = 2500,
        max_elongation: float = 6.0,
        min_fill: float = 0.35,
        change_fraction: float = 0.2,
        busy_frames: int = 45,
        track_px: float = 80.0,
        busy_gain: float = 60.0,
        bands: int = 8,
        max_darker: float = 0.2,
        min_cross: float = 0.04,
        busy_events: int = 2,
        position: str = "beam",
        new_margin: int = _NEW_MARGIN,
        confirm: int = 1,
        busy_confirm: int = 2,
        min_rise: float = 15.0,
        fringe_ratio: float = 1.15,
        hold_spot: bool = True,
        peak_margin: int = 3,
        beam_channels: int = 3,
        bright_rise: int = 10,
        search_first: bool = True,
    ) -> None:
        if colour not in COLOURS:
            raise ValueError(f"colour must be one of {', '.join(COLOURS)}, got {colour!r}")
        if step < 1:
            raise ValueError(f"step must be >= 1 pixel, got {step}")
        if not 0 < rise < 255 or not _NEW_MARGIN < saturated <= 255 or not 0 < soft < saturated:
            raise ValueError(
                f"need rise 1..254, saturated {_NEW_MARGIN + 1}..255 and 0 < soft < saturated,"
                f" got {rise}, {saturated}, {soft}"
            )
        if not 1 <= min_area <= max_area:
            raise ValueError(f"need 1 <= min_area <= max_area, got {min_area}, {max_area}")
        if max_elongation < 1.0 or not 0.0 <= min_fill <= 1.0 or not 0.0 <= min_new <= 1.0:
            raise ValueError("need max_elongation >= 1, 0 <= min_fill <= 1, 0 <= min_new <= 1")
        if halo < 0 or colour_ratio < 0 or busy_gain < 0 or not 0 <= fringe <= 1:
            raise ValueError(
                "need halo >= 0, colour_ratio >= 0, busy_gain >= 0 and 0 <= fringe <= 1, got"
                f" {halo}, {colour_ratio}, {busy_gain}, {fringe}"
            )
        if not 0 <= min_cross < 255:
            raise ValueError(f"need 0 <= min_cross < 255, got {min_cross}")
        if not 0 < change_fraction <= 1 or bands < 1 or busy_frames < 0 or track_px <= 0:
            raise ValueError(
                "need 0 < change_fraction <= 1, bands >= 1, busy_frames >= 0, track_px > 0"
            )
        self.colour = colour
        self.channels = (2, 1) if colour == "any" else (LASER_CHANNEL[colour],)
        self.mask = None if mask is None else np.ascontiguousarray(mask, dtype=bool)
        self.step = step
        self.saturated = saturated
        self.soft = soft
        self.rise = rise
        self.halo = halo
        self.colour_ratio = colour_ratio
        self.fringe = fringe
        self.min_new = min_new
        self.min_area = min_area
        self.max_area = max_area
        self.max_elongation = max_elongation
        self.min_fill = min_fill
        self.change_fraction = change_fraction
        self.busy_frames = busy_frames
        self.track_px = track_px
        self.busy_gain = busy_gain
        self.bands = bands
        if not 0.0 <= max_darker <= 1.0:
            raise ValueError(f"need 0 <= max_darker <= 1, got {max_darker}")
        if position not in ("fit", "centroid", "beam"):
            raise ValueError(f"position must be 'beam', 'centroid' or 'fit', got {position!r}")
        self.max_darker = max_darker
        self.min_cross = min_cross
        if not 1 <= busy_events <= 16:
            raise ValueError(f"need busy_events 1..16, got {busy_events}")
        self.busy_events = busy_events
        self.position = position
        if not 1 <= new_margin < saturated:
            raise ValueError(f"need 1 <= new_margin < saturated, got {new_margin}")
        self.new_margin = new_margin
        if not 1 <= confirm <= 10:
            raise ValueError(f"need confirm 1..10, got {confirm}")
        self.confirm = confirm
        if not 1 <= busy_confirm <= 10:
            raise ValueError(f"need busy_confirm 1..10, got {busy_confirm}")
        self.busy_confirm = busy_confirm
        if not 0.0 <= min_rise < 255.0 or fringe_ratio < 0.0:
            raise ValueError(
                f"need 0 <= min_rise < 255 and fringe_ratio >= 0, got {min_rise}, {fringe_ratio}"
            )
        self.min_rise = min_rise
        self.fringe_ratio = fringe_ratio
        self.hold_spot = hold_spot
        if not 0 <= peak_margin <= 255:
            raise ValueError(f"need peak_margin 0..255, got {peak_margin}")
        self.peak_margin = peak_margin
        if beam_channels not in (1, 3):
            raise ValueError(f"need beam_channels 1 or 3, got {beam_channels}")
        self.beam_channels = beam_channels
        if not 0 <= bright_rise < 255:
            raise ValueError(f"need bright_rise 0..254, got {bright_rise}")
        self.bright_rise = bright_rise
        self.search_first = search_first
        self._kernels: dict[int, NDArray[np.uint8]] = {}  # elliptic kernels by size
        self._top: dict[int, int] = {}  # laser channel -> highest level seen on the screen
        self._need = confirm  # frames the current track needs before it is reported
        self._run = 0  # frames in a row with a spot, each near the one before
        self.half = math.ceil(math.sqrt(max_area / math.pi)) + 12  # window half size, px
        self._k3 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
        self._k5 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
        self._k7 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
        self._k11 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (11, 11))
        self._k19 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (19, 19))
        self._k25 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (25, 25))
        self._kgrow = np.ones((2 * step + 1,) * 2, np.uint8)
        self.background: NDArray[np.uint8] | None = None
        self.slide_changes = 0  # frames judged a slide change (for figures)
        self.refused = 0  # frames refused as ambiguous (for figures)
        # the last frame's blobs that failed a test: (image box rows r0:r1, cols c0:c1,
        # the test: "shape", "peak", "no model", "busy", "not new", "darker", "cross",
        # "rise", "colour"), and whether a spot passed but its track is not yet
        # confirmed (for figures: why a spot was missed)
        self.rejected: list[tuple[tuple[int, int, int, int], str]] = []
        self.unconfirmed = False
        self._planes: dict[int, NDArray[np.uint8]] = {}  # laser channels of the model
        self._low: dict[int, NDArray[np.uint8]] = {}  # where a clipped pixel would be new
        # where the laser channel is near clipping but the others have room to rise
        self._bright: dict[int, NDArray[np.uint8]] = {}
        self._bright_n: dict[int, int] = {}  # pixels of each channel's _bright
        self._bg_lo = np.zeros((0, 0, 3), np.uint8)  # the model at the sampled pixels
        self._frame = 0
        self._mask8: NDArray[np.uint8] | None = None
        self._mask_lo: NDArray[np.uint8] | None = None
        self._mask_count = 1
        self._busy = np.zeros((0, 0), np.int32)  # per block: frame until which it is busy
        self._history = np.zeros((0, 0), np.uint16)  # per block: frames with darker content
        self._last: LaserSpot | None = None
        # with ``search_first`` off, the model before this frame's darker pixels replaced
        # it: (row, col, values)
        self._prefix: tuple[int, int, NDArray[np.uint8]] | None = None

    def reset(self) -> None:
        """Forget the content model (the next frame starts it again)."""
        self.background = None
        self._last = None
        self._run = 0
        self._top = {}

    # -- per frame -------------------------------------------------------------------

    def detect(self, image: NDArray[np.uint8]) -> LaserSpot | None:
        """The laser spot in a BGR H x W x 3 uint8 frame, or None; updates the model."""
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"need an H x W x 3 uint8 BGR image, got {image.dtype} {image.shape}")
        h, w = image.shape[:2]
        if self.mask is not None and self.mask.shape != (h, w):
            raise ValueError(f"mask is {self.mask.shape[1]}x{self.mask.shape[0]}, image {w}x{h}")
        self.rejected = []
        self.unconfirmed = False
        bg = self.background
        if bg is None or bg.shape != image.shape:
            self._start(image)  # nothing to compare with yet
            spot = None
        else:
            spot = self._detect(image, bg)
        last, self._last = self._last, spot
        if spot is None:
            self._frame += 1
            self._run = 0
            return None
        near = last is not None and math.hypot(last.u - spot.u, last.v - spot.v) <= self.track_px
        if near:
            self._run += 1
        else:  # a new track: in a busy region it needs ``busy_confirm`` frames
            self._run = 1
            self._need = self.confirm
            if self.busy_confirm > self.confirm and self._is_busy(spot.u, spot.v):
                self._need = self.busy_confirm
        self._frame += 1
        self.unconfirmed = self._run < self._need
        return None if self.unconfirmed else spot

    def _detect(self, image: NDArray[np.uint8], bg: NDArray[np.uint8]) -> LaserSpot | None:
        k = self.step
        lo, bg_lo = cv2.split(_sample(image, k)), cv2.split(self._bg_lo)
        changed = 0
        dec_any: NDArray[Any] | None = None
        for c in self.channels:
            lc, bc = lo[c], bg_lo[c]
            a, b = (o for o in (0, 1, 2) if o != c)
            o, bo = cv2.max(lo[a], lo[b]), cv2.max(bg_lo[a], bg_lo[b])
            dec = cv2.max(cv2.subtract(bc, lc), cv2.subtract(bo, o))
            ch = cv2.max(cv2.max(cv2.subtract(lc, bc), dec), cv2.subtract(o, bo))
            if self._mask_lo is not None:
                ch = cv2.bitwise_and(ch, self._mask_lo)
                dec = cv2.bitwise_and(dec, self._mask_lo)
            changed = max(changed, cv2.countNonZero(cv2.threshold(ch, self.rise - 1, 255, 0)[1]))
            dec_any = dec if dec_any is None else np.asarray(cv2.max(dec_any, dec), np.uint8)
        assert dec_any is not None
        if changed > self.change_fraction * self._mask_count:
            self.slide_changes += 1
            return self._restart(image)
        self._mark_busy(dec_any)
        self._prefix = None
        if not self.search_first:
            self._fix_darker(image, dec_any)
        cands = []
        clipped_of: dict[int, NDArray[np.uint8]] = {}
        for c in self.channels:
            lc = np.asarray(cv2.extractChannel(image, c), np.uint8)
            if self.peak_margin < 255 and self._top.get(c, 0) < 255:
                top = int(cv2.minMaxLoc(lc, self._mask8)[1])
                self._top[c] = max(self._top.get(c, 0), top)
            clipped = np.asarray(
                cv2.threshold(lc, self.saturated - 1, 255, cv2.THRESH_BINARY)[1], np.uint8
            )
            clipped_of[c] = clipped
            cand = np.asarray(cv2.bitwise_and(clipped, self._low[c]), np.uint8)
            if self.bright_rise > 0:
                self._add_bright(image, bg, c, clipped, cand)
            cands.append((c, cand))
        spot = self._best(image, cands, bg, near_only=False)
        # after the search, so that a spot is judged against the model as it was (a
        # codec's chroma bleed darkens the other channels around a new spot, and the
        # fix's reach would take half the spot into the model), and its window is held
        if self.search_first:
            self._fix_darker(image, dec_any, spot)
        self._update(image, spot, clipped_of)
        return spot

    def _add_bright(
        self,
        image: NDArray[np.uint8],
        bg: NDArray[np.uint8],
        c: int,
        clipped: NDArray[np.uint8],
        cand: NDArray[np.uint8],
    ) -> None:
        """Add to ``cand`` the clipped pixels over content already near clipping in the
        laser channel (a spot on a bright page of the laser's colour: its channel has no
        room to rise) where the strongest other channel rose over the model by
        ``bright_rise`` grey levels (the laser's light leaking into them)."""
        if not self._bright_n[c]:
            return
        hi = cv2.bitwise_and(clipped, self._bright[c])
        if not cv2.countNonZero(hi):
            return
        x, y, w, h = cv2.boundingRect(hi)
        rows, cols = slice(y, y + h), slice(x, x + w)
        up = cv2.subtract(self._others(image[rows, cols], c), self._others(bg[rows, cols], c))
        rose = cv2.threshold(up, self.bright_rise - 1, 255, cv2.THRESH_BINARY)[1]
        cand[rows, cols] = cv2.max(cand[rows, cols], cv2.bitwise_and(hi[rows, cols], rose))

    @staticmethod
    def _others(img: NDArray[np.uint8], c: int) -> NDArray[np.uint8]:
        a, b = (o for o in (0, 1, 2) if o != c)
        out = cv2.max(np.ascontiguousarray(img[:, :, a]), np.ascontiguousarray(img[:, :, b]))
        return np.asarray(out, np.uint8)

    # -- the model -------------------------------------------------------------------

    def _start(self, image: NDArray[np.uint8]) -> None:
        h, w = image.shape[:2]
        k = self.step
        if self.mask is not None:
            self._mask8 = self.mask.astype(np.uint8) * 255
            self._mask_lo = np.ascontiguousarray(self._mask8[::k, ::k])
            self._mask_count = max(1, cv2.countNonZero(self._mask_lo))
        else:
            self._mask8 = self._mask_lo = None
            self._mask_count = len(range(0, h, k)) * len(range(0, w, k))
        self._busy = np.full((-(-h // _BLOCK), -(-w // _BLOCK)), -1, np.int32)
        self._history = np.zeros(self._busy.shape, np.uint16)
        self._set_model(image.copy())

    def _set_model(self, bg: NDArray[np.uint8]) -> None:
        self.background = bg
        self._planes = {c: np.ascontiguousarray(bg[:, :, c]) for c in self.channels}
        self._bg_lo = np.ascontiguousarray(_sample(bg, self.step))
        self._low = {c: self._low_of(p, slice(None), slice(None)) for c, p in self._planes.items()}
        if self.bright_rise > 0:
            every = (slice(None), slice(None))
            self._bright = {c: self._bright_of(c, *every) for c in self.channels}
            self._bright_n = {c: cv2.countNonZero(b) for c, b in self._bright.items()}

    def _low_of(self, plane: NDArray[np.uint8], rows: slice, cols: slice) -> NDArray[np.uint8]:
        """255 where the model's laser channel is clearly below clipping (a pixel that
        clips there now is new) and inside the screen, else 0."""
        low = cv2.threshold(
            np.ascontiguousarray(plane[rows, cols]),
            self.saturated - self.new_margin - 1,
            255,
            cv2.THRESH_BINARY_INV,
        )[1]
        if self._mask8 is not None:
            low = cv2.bitwise_and(low, np.ascontiguousarray(self._mask8[rows, cols]))
        out: NDArray[np.uint8] = np.asarray(low, np.uint8)
        return out

    def _bright_of(self, c: int, rows: slice, cols: slice) -> NDArray[np.uint8]:
        """255 inside the screen where the model's laser channel ``c`` is near clipping
        (not :meth:`_low_of`) and its other channels have ``bright_rise`` of room."""
        assert self.background is not None
        plane = self._planes[c][rows, cols]
        near = cv2.threshold(plane, self.saturated - self.new_margin - 1, 255, 0)[1]
        out = np.zeros(plane.shape, np.uint8)
        if not cv2.countNonZero(near):  # the common case: nothing near clipping
            return out
        x, y, w, h = cv2.boundingRect(near)
        r = slice(y, y + h)
        q = slice(x, x + w)
        bg = self.background[rows, cols][r, q]
        room = cv2.threshold(self._others(bg, c), 255 - self.bright_rise, 255, 1)[1]
        part = cv2.bitwise_and(room, near[r, q])
        if self._mask8 is not None:
            part = cv2.bitwise_and(part, np.ascontiguousarray(self._mask8[rows, cols][r, q]))
        out[r, q] = part
        return out

    def _set_bright(self, c: int, rows: slice, cols: slice) -> None:
        """Refresh :attr:`_bright` of channel ``c`` in a region, and its pixel count."""
        new = self._bright_of(c, rows, cols)
        old = self._bright[c][rows, cols]
        self._bright_n[c] += cv2.countNonZero(new) - cv2.countNonZero(old)
        old[:] = new

    def _model_changed(self, rows: slice, cols: slice = slice(None)) -> None:
        bg = self.background
        assert bg is not None
        for c, plane in self._planes.items():
            plane[rows, cols] = bg[rows, cols, c]
            self._low[c][rows, cols] = self._low_of(plane, rows, cols)
            if self.bright_rise > 0:
                self._set_bright(c, rows, cols)
        k = self.step  # and the sampled model, on the sampled rows and columns in there
        h, w = bg.shape[:2]
        r0, r1, _ = rows.indices(h)
        c0, c1, _ = cols.indices(w)
        i0, j0 = -(-r0 // k), -(-c0 // k)
        self._bg_lo[i0 : -(-r1 // k), j0 : -(-c1 // k)] = bg[i0 * k : r1 : k, j0 * k : c1 : k]

    def _mark_busy(self, dec: NDArray[np.uint8]) -> None:
        """Blocks where much of the content got darker (>= 10 % of the samples by
        ``rise``) in two of the last 16 frames are busy for ``busy_frames`` frames,
        with their neighbours."""
        self._history = np.asarray((self._history << 1) & 0xFFFF, np.uint16)
        if self.busy_frames == 0:
            return
        hit = cv2.threshold(dec, self.rise - 1, 1, 0)[1]
        if not cv2.countNonZero(hit):
            return
        bh, bw = self._busy.shape
        kb = max(1, _BLOCK // self.step)
        pad_h, pad_w = bh * kb - hit.shape[0], bw * kb - hit.shape[1]
        if pad_h > 0 or pad_w > 0:
            hit = cv2.copyMakeBorder(hit, 0, max(0, pad_h), 0, max(0, pad_w), cv2.BORDER_CONSTANT)
        # the fraction of each block's samples that got darker (area mean: exact here)
        frac = cv2.resize(
            hit[: bh * kb, : bw * kb].astype(np.float32), (bw, bh), interpolation=cv2.INTER_AREA
        )
        self._history[frac >= 0.1] |= 1
        counts = _POPCOUNT[self._history & 0xFF] + _POPCOUNT[self._history >> 8]
        many = (counts >= self.busy_events).astype(np.uint8)
        busy = cv2.dilate(many, np.ones((3, 3), np.uint8)).astype(bool)
        self._busy[busy] = self._frame + self.busy_frames

    def _is_busy(self, u: float, v: float) -> bool:
        bh, bw = self._busy.shape
        r = min(bh - 1, max(0, int(v) // _BLOCK))
        c = min(bw - 1, max(0, int(u) // _BLOCK))
        return bool(self._busy[r, c] >= self._frame)

    def _fix_darker(
        self, image: NDArray[np.uint8], dec: NDArray[np.uint8], spot: LaserSpot | None = None
    ) -> None:
        """Where the frame is darker than the model by ``rise`` the model is out of date
        (content changed, or it held a spot): those pixels take the frame's values."""
        bg = self.background
        assert bg is not None
        hit = cv2.threshold(dec, self.rise - 1, 255, 0)[1]
        if not cv2.countNonZero(hit):
            return
        k = self.step
        h, w = image.shape[:2]
        x, y, bw, bh = cv2.boundingRect(hit)
        r0, c0 = max(0, (y - 1) * k), max(0, (x - 1) * k)
        r1, c1 = min(h, (y + bh + 1) * k), min(w, (x + bw + 1) * k)
        sub = hit[r0 // k : -(-r1 // k), c0 // k : -(-c1 // k)]
        full = cv2.resize(sub, None, fx=k, fy=k, interpolation=cv2.INTER_NEAREST)
        full = np.ascontiguousarray(full[: r1 - r0, : c1 - c0])
        grown = cv2.dilate(full, self._kgrow)
        for held in (self._last, spot):
            if not self.hold_spot or held is None:
                continue
            # this and the last spot's window never take pixels where the laser channel
            # rose: content changing next to a spot would copy the spot into the model
            v0, v1, u0, u1 = self._window(held.u, held.v, h, w)
            a0, a1, b0, b1 = max(v0, r0), min(v1, r1), max(u0, c0), min(u1, c1)
            if a0 < a1 and b0 < b1:
                for c in self.channels:
                    up = cv2.subtract(image[a0:a1, b0:b1, c], bg[a0:a1, b0:b1, c])
                    grown[a0 - r0 : a1 - r0, b0 - c0 : b1 - c0][up >= self.rise] = 0
        if not self.search_first:
            self._prefix = (r0, c0, bg[r0:r1, c0:c1].copy())
        cv2.copyTo(image[r0:r1, c0:c1], grown, bg[r0:r1, c0:c1])
        self._model_changed(slice(r0, r1), slice(c0, c1))

    def _restart(self, image: NDArray[np.uint8]) -> LaserSpot | None:
        """A slide change: look for the spot near the previous one; the model restarts
        from the frame without the spot's footprint."""
        cands = []
        for c in self.channels:
            clipped = cv2.threshold(cv2.extractChannel(image, c), self.saturated - 1, 255, 0)[1]
            if self._mask8 is not None:
                clipped = cv2.bitwise_and(clipped, self._mask8)
            cands.append((c, clipped))
        spot = self._best(image, cands, None, near_only=True)
        bg = image.copy()
        if spot is not None:
            self._carve(image, bg, spot)
        self._set_model(bg)
        return spot

    def _carve(self, image: NDArray[np.uint8], bg: NDArray[np.uint8], spot: LaserSpot) -> None:
        """Take the spot out of model ``bg``: in its window, pixels where a laser channel
        stands above the window's grey opening get the opening's values."""
        h, w = image.shape[:2]
        v0, v1, u0, u1 = self._window(spot.u, spot.v, h, w)
        win = image[v0:v1, u0:u1]
        size = 2 * math.ceil(1.5 * math.sqrt(max(spot.area, 4) / math.pi)) + 3
        opened = cv2.morphologyEx(win, cv2.MORPH_OPEN, np.ones((size, size), np.uint8))
        foot = np.zeros(win.shape[:2], np.uint8)
        for c in self.channels:
            foot |= (cv2.subtract(win[:, :, c], opened[:, :, c]) >= self.rise // 2).astype(np.uint8)
        grown = cv2.dilate(foot, self._k7).view(bool)
        bg[v0:v1, u0:u1][grown] = opened[grown]

    def _update(
        self,
        image: NDArray[np.uint8],
        spot: LaserSpot | None,
        clipped_of: dict[int, NDArray[np.uint8]],
    ) -> None:
        """Blend one row band of the frame into the model, except where a laser channel
        newly clipped (a spot, found or not; ``clipped_of``: per laser channel, 255 where
        the frame clips it) and the spot's window."""
        bg = self.background
        assert bg is not None
        h, w = image.shape[:2]
        band = -(-h // self.bands)
        b0 = (self._frame % self.bands) * band
        b1 = min(h, b0 + band)
        if b0 >= b1:
            return
        keep = np.zeros((b1 - b0, w), np.uint8)
        band = image[b0:b1]
        for c, plane in self._planes.items():
            clipped = clipped_of[c][b0:b1]
            was_low = cv2.threshold(plane[b0:b1], self.saturated - self.new_margin - 1, 1, 1)[1]
            keep = cv2.max(keep, cv2.bitwise_and(clipped, was_low))
        if spot is not None:
            v0, v1, u0, u1 = self._window(spot.u, spot.v, h, w)
            if v0 < b1 and b0 < v1:
                keep[max(v0, b0) - b0 : min(v1, b1) - b0, u0:u1] = 1
        x, y, kw, kh = cv2.boundingRect(keep)
        if kw:  # and the halo around it (12 px), which would leave darker pixels behind
            y0, y1 = max(0, y - 12), min(b1 - b0, y + kh + 12)
            x0, x1 = max(0, x - 12), min(w, x + kw + 12)
            keep = np.ascontiguousarray(keep[y0:y1, x0:x1])
            keep = cv2.dilate(keep, self._k25, borderType=cv2.BORDER_CONSTANT, borderValue=0)
            saved = bg[b0 + y0 : b0 + y1, x0:x1].copy()
        cv2.addWeighted(band, 0.5, bg[b0:b1], 0.5, 0.0, dst=bg[b0:b1])
        if kw:
            cv2.copyTo(saved, keep, bg[b0 + y0 : b0 + y1, x0:x1])
        self._model_changed(slice(b0, b1))

    def _window(self, u: float, v: float, h: int, w: int) -> tuple[int, int, int, int]:
        r = self.half
        cu, cv_ = round(u), round(v)
        return max(0, cv_ - r), min(h, cv_ + r + 1), max(0, cu - r), min(w, cu + r + 1)

    # -- candidates ------------------------------------------------------------------

    def _best(
        self,
        image: NDArray[np.uint8],
        cands: list[tuple[int, NDArray[Any]]],
        bg: NDArray[np.uint8] | None,
        *,
        near_only: bool,
    ) -> LaserSpot | None:
        """The spot among candidate pixels per laser channel (``bg`` None: no model)."""
        h, w = image.shape[:2]
        last = self._last
        seeds: list[tuple[int, int, int]] = []
        for c, cand in cands:
            if last is not None:  # clipped pixels near the last spot are candidates too
                v0, v1, u0, u1 = self._window(last.u, last.v, h, w)
                near = cv2.threshold(image[v0:v1, u0:u1, c], self.saturated - 1, 255, 0)[1]
                if self._mask8 is not None:
                    near = cv2.bitwise_and(near, self._mask8[v0:v1, u0:u1])
                if near_only:
                    cand = np.zeros_like(cand)
                cand[v0:v1, u0:u1] = cv2.max(cand[v0:v1, u0:u1], near)
            elif near_only:
                continue
            if not cv2.countNonZero(cand):
                continue
            x0, y0, bw, bh = cv2.boundingRect(cand)
            _, lab, st, _ = cv2.connectedComponentsWithStats(
                np.ascontiguousarray(cand[y0 : y0 + bh, x0 : x0 + bw]), connectivity=8
            )
            order = np.argsort(-st[1:, cv2.CC_STAT_AREA]) + 1
            for j in order[:64]:  # a pixel of each group, the largest groups first
                gx, gy = st[j, cv2.CC_STAT_LEFT], st[j, cv2.CC_STAT_TOP]
                row = lab[gy, gx : gx + st[j, cv2.CC_STAT_WIDTH]]
                gx += int(np.argmax(row == j))
                seeds.append((c, int(x0 + gx), int(y0 + gy)))
        found: list[LaserSpot] = []
        measured: list[tuple[int, int, int, int]] = []  # image boxes already measured
        tried = 0
        for c, su, sv in seeds:
            if any(v0 <= sv < v1 and u0 <= su < u1 for v0, v1, u0, u1 in measured):
                continue
            spot, blob_box = self._measure(image, bg, c, su, sv, h, w)
            tried += 1
            measured.append(blob_box if blob_box is not None else (sv, sv + 1, su, su + 1))
            if spot is not None:
                found.append(spot)
            if tried >= 48:
                break
        if not found:
            return None
        found.sort(key=lambda s: -s.score)
        best = found[0]
        for other in found[1:]:
            far = math.hypot(other.u - best.u, other.v - best.v) > 2 * self.half
            if far and other.score >= 0.5 * best.score:
                self.refused += 1
                return None
        return best

    def _measure(
        self,
        image: NDArray[np.uint8],
        bg: NDArray[np.uint8] | None,
        c: int,
        su: int,
        sv: int,
        h: int,
        w: int,
    ) -> tuple[LaserSpot | None, tuple[int, int, int, int] | None]:
        """The blob of clipped laser channel ``c`` through full-res pixel (su, sv): the
        spot if it passes, and the image box the blob covers (None: too large or none)."""
        v0, v1, u0, u1 = self._window(float(su), float(sv), h, w)
        win = image[v0:v1, u0:u1]
        lc = win[:, :, c]
        sel, box = self._blob(lc >= self.saturated, su - u0, sv - v0)
        if box is None:
            return None, None
        ibox = (box[0] + v0, box[1] + v0, box[2] + u0, box[3] + u0)
        if sel is None:
            return self._reject(ibox, "shape")
        if int(lc[sel].max()) < self._top.get(c, 0) - self.peak_margin:
            return self._reject(ibox, "peak")  # a spot drives its channel to the top
        # every test below looks at most r + 7 px beyond the blob (the ring's outer band,
        # the fits' reach, cut here): measure in that part of the window only
        m = math.ceil(max(4.0, math.sqrt(np.count_nonzero(sel) / math.pi))) + 7
        r0, c0 = max(0, box[0] - m), max(0, box[2] - m)
        r1, c1 = min(sel.shape[0], box[1] + m), min(sel.shape[1], box[3] + m)
        sel, lc = sel[r0:r1, c0:c1], lc[r0:r1, c0:c1]
        box = (box[0] - r0, box[1] - r0, box[2] - c0, box[3] - c0)
        v0, v1, u0, u1 = v0 + r0, v0 + r1, u0 + c0, u0 + c1
        win = image[v0:v1, u0:u1]
        last = self._last
        near = last is not None and math.hypot(last.u - su, last.v - sv) <= self.track_px
        if bg is None and not near:
            return self._reject(ibox, "no model")
        busy = bg is not None and self._is_busy(su, sv)
        if busy and not near:
            # content moves here: only a blob far more of the laser's colour than its
            # surroundings (its ring) starts a track
            g = self._ring_gain(win, sel, c)
            if g is None or g < self.busy_gain:
                return self._reject(ibox, "busy")
        bright = False  # over content near clipping in the laser channel
        if bg is not None:
            # new: enough of the blob was not clipped in the content model
            was = self._planes[c][v0:v1, u0:u1][sel]
            if np.count_nonzero(was < self.saturated - self.new_margin) < self.min_new * was.size:
                if (
                    self.bright_rise <= 0
                    or busy
                    or not self._bright_new(win, bg[v0:v1, u0:u1], sel, c)
                ):
                    return self._reject(ibox, "not new")
                bright = True
        model = None if bg is None else self._model_window(bg, v0, v1, u0, u1)
        if model is not None and not self._adds_light(win, model, sel):
            return self._reject(ibox, "darker")
        if model is not None and not self._cross_rise(win, model, sel, c):
            return self._reject(ibox, "cross")
        if model is not None and self.min_rise > 0:
            disc = cv2.dilate(sel.view(np.uint8), self._k5).view(bool)
            if bright:  # the laser channel had no room: its light in the others
                up = cv2.subtract(self._others(win, c), self._others(model, c))[disc]
            else:
                up = win[:, :, c][disc].astype(np.int16) - model[:, :, c][disc]
            if float(up.mean()) < self.min_rise:
                return self._reject(ibox, "rise")
        gain = self._colour(win, None if bg is None or busy else bg[v0:v1, u0:u1], sel, c)
        if gain is None:
            return self._reject(ibox, "colour")
        region = cv2.dilate(sel.view(np.uint8), self._k3).view(bool)
        lo_edge = self.saturated - self.soft
        wgt = np.clip((lc[region].astype(np.float64) - lo_edge) / self.soft, 0, 1)
        ys, xs = np.nonzero(region)
        tot = float(wgt.sum())
        area = int(np.count_nonzero(sel))
        pu, pv = float((wgt * xs).sum()) / tot, float((wgt * ys).sum()) / tot
        if model is not None and self.position == "beam":
            bc = self._beam_centre(win, model, sel, c, pu, pv)
            if bc is not None:
                pu, pv = bc
        if model is not None and self.position == "fit":
            fit = self._fit_centre(win, model, sel, c)
            reach = 0.25 * (box[3] - box[2] + box[1] - box[0]) + 1.0
            if fit is not None and math.hypot(fit[0] - pu, fit[1] - pv) <= reach:
                pu, pv = fit
        spot = LaserSpot(
            pu + u0,
            pv + v0,
            area,
            int(lc[sel].max()),
            area * gain,
            "red" if c == 2 else "green",
        )
        return spot, ibox

    def _reject(
        self, box: tuple[int, int, int, int], why: str
    ) -> tuple[None, tuple[int, int, int, int]]:
        """Note a blob that failed test ``why`` (:attr:`rejected`); (None, its box)."""
        self.rejected.append((box, why))
        return None, box

    def _bright_new(
        self, win: NDArray[np.uint8], ref: NDArray[np.uint8], sel: NDArray[np.bool_], c: int
    ) -> bool:
        """New over content near clipping: the strongest other channel rose over the
        model ``ref`` (the same window) by ``bright_rise`` on at least ``min_new`` of the
        blob."""
        up = cv2.subtract(self._others(win, c), self._others(ref, c))[sel]
        return bool(np.count_nonzero(up >= self.bright_rise) >= self.min_new * up.size)

    def _model_window(
        self, bg: NDArray[np.uint8], v0: int, v1: int, u0: int, u1: int
    ) -> NDArray[np.uint8]:
        """The content model in a window as it was before this frame's darker pixels
        replaced it (they replace it before the search only with ``search_first`` off)."""
        out = bg[v0:v1, u0:u1]
        if self._prefix is None:
            return out
        r0, c0, saved = self._prefix
        a0, a1 = max(v0, r0), min(v1, r0 + saved.shape[0])
        b0, b1 = max(u0, c0), min(u1, c0 + saved.shape[1])
        if a0 >= a1 or b0 >= b1:
            return out
        out = out.copy()
        out[a0 - v0 : a1 - v0, b0 - u0 : b1 - u0] = saved[a0 - r0 : a1 - r0, b0 - c0 : b1 - c0]
        return out

    def _adds_light(
        self, win: NDArray[np.uint8], model: NDArray[np.uint8], sel: NDArray[np.bool_]
    ) -> bool:
        """A laser only adds light: over the blob and the 3 px around it, at most
        ``max_darker`` of the pixels may have any channel darker than the model by
        ``rise`` (content of the laser's colour moving in replaces what was there)."""
        grown = cv2.dilate(sel.view(np.uint8), self._k7).view(bool)
        drop = cv2.subtract(model, win).max(axis=2)[grown]
        return bool(np.count_nonzero(drop >= self.rise) <= self.max_darker * drop.size)

    def _cross_rise(
        self,
        win: NDArray[np.uint8],
        model: NDArray[np.uint8],
        sel: NDArray[np.bool_],
        c: int,
    ) -> bool:
        """A laser's light reaches the other channels too (a colour filter passes some of
        every wavelength; chroma subsampling adds more): over the blob, the upper half of
        the strongest other channel's rise over the model, in linear light, is at least
        ``min_cross`` (content of the laser's colour appearing raises only its channel;
        where the other channels already clip, nothing is asked)."""
        if self.min_cross <= 0:
            return True
        a, b = (o for o in (0, 1, 2) if o != c)
        now = np.maximum(win[:, :, a], win[:, :, b])[sel]
        was = np.maximum(model[:, :, a], model[:, :, b])[sel]
        room = _LIN[255] - _LIN[was]
        rise = _LIN[now] - _LIN[was]
        srt = np.sort(np.where(room < self.min_cross, self.min_cross, rise))
        return bool(srt[srt.size // 2 :].mean() >= self.min_cross)

    def _beam_centre(
        self,
        win: NDArray[np.uint8],
        model: NDArray[np.uint8],
        sel: NDArray[np.bool_],
        c: int,
        pu: float,
        pv: float,
    ) -> tuple[float, float] | None:
        """The beam's centre (window px) from a round Gaussian fitted to the laser
        channel's rise over the model in linear light, ``b + A exp(-d^2 / 2 s^2)``, where
        clipped pixels say only that the beam filled the room the content left there
        (censored), so neither the content under the spot nor where it clips bends the
        centre; with ``beam_channels`` 3 the other channels' rise too, each with its own
        A, s, b (:func:`_fit_beams`). Levenberg-Marquardt from the blob's centroid
        (pu, pv). None if the fit fails or moves further than the blob's radius."""
        area = int(np.count_nonzero(sel))
        r = max(1.5, math.sqrt(area / math.pi))
        size = 2 * math.ceil(r + 3) + 1
        if size not in self._kernels:
            self._kernels[size] = np.asarray(
                cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size)), np.uint8
            )
        ker = self._kernels[size]
        grown = cv2.dilate(sel.view(np.uint8), ker).view(bool)
        ys, xs = np.nonzero(grown)
        if self.beam_channels == 1:
            now, was = win[:, :, c][grown][None, :], _LIN[model[:, :, c][grown]][None, :]
        else:  # all three, in BGR order (the fit treats its channels alike)
            now, was = win[grown].T, _LIN[model[grown].T]
        cens = now >= self.saturated
        room = 1.0 - was
        rise = _LIN[now] - was
        start = [pu, pv]
        for j in range(now.shape[0]):
            rc = room[j][cens[j]]  # twice the censored rooms' (upper) median, to start
            if rc.size:
                peak = 2.0 * float(np.partition(rc, rc.size // 2)[rc.size // 2])
            else:
                peak = float(rise[j].max())
            start += [math.log(max(peak, 1e-3)), math.log(r), 0.0]
        x, y = xs.astype(np.float64), ys.astype(np.float64)
        fit = _fit_beams(x, y, rise, room, cens, np.array(start))
        if fit is None or math.hypot(fit[0] - pu, fit[1] - pv) > r + 1.0:
            return None
        return fit

    def _fit_centre(
        self,
        win: NDArray[np.uint8],
        model: NDArray[np.uint8],
        sel: NDArray[np.bool_],
        c: int,
    ) -> tuple[float, float] | None:
        """The beam's centre (window px) from the laser channel's rise over the model in
        linear light on the unclipped pixels around the blob: a weighted least-squares fit
        of ``ln rise = a + b u + c v + d (u^2 + v^2)`` (a round beam; the clipped core,
        whose shape follows the content under it, is left out). None if it does not fit."""
        r = max(2.0, math.sqrt(np.count_nonzero(sel) / math.pi))
        size = 2 * math.ceil(r + 4) + 1
        ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
        grown = cv2.dilate(sel.view(np.uint8), ker).view(bool)
        lc = win[:, :, c]
        rise = _LIN[lc] - _LIN[model[:, :, c]]
        use = grown & ~sel & (lc < self.saturated) & (rise > 0.02)
        n = int(np.count_nonzero(use))
        if n < 8:
            return None
        ys, xs = np.nonzero(use)
        y = np.log(rise[use])
        w = rise[use]
        xm, ym = float(xs.mean()), float(ys.mean())
        dx, dy = xs - xm, ys - ym
        A = np.column_stack([np.ones(n), dx, dy, dx * dx + dy * dy])
        sol, *_ = np.linalg.lstsq(A * w[:, None], y * w, rcond=None)
        d = float(sol[3])
        if not d < -1e-4:
            return None
        return xm - float(sol[1]) / (2 * d), ym - float(sol[2]) / (2 * d)

    def _blob(
        self, binary: NDArray[np.bool_], su: int, sv: int
    ) -> tuple[NDArray[np.bool_] | None, tuple[int, int, int, int] | None]:
        """The connected blob of ``binary`` through (su, sv) if its size and shape fit,
        and its box (rows r0:r1, cols c0:c1 of the window; None if it is not there)."""
        if not binary[sv, su]:
            return None, None
        # the 8-connected blob through the seed (a flood fill visits only the blob)
        wh, ww = binary.shape
        fill = np.zeros((wh + 2, ww + 2), np.uint8)
        flags = 8 | cv2.FLOODFILL_MASK_ONLY | (1 << 8)
        area, _, _, (x, y, bw, bh) = cv2.floodFill(
            binary.view(np.uint8), fill, (su, sv), 0, 0, 0, flags
        )
        sel: NDArray[np.bool_] = fill[1:-1, 1:-1].view(bool)
        box = (y, y + bh, x, x + bw)
        if not self.min_area <= area <= self.max_area:
            return None, box
        if box[0] == 0 or box[2] == 0 or box[1] == wh or box[3] == ww:
            return None, box  # runs out of the window: larger than a spot
        if area >= 5:
            ys, xs = np.nonzero(sel)
            xm, ym = xs.mean(), ys.mean()
            cxx = float(((xs - xm) ** 2).mean()) + 1 / 12
            cyy = float(((ys - ym) ** 2).mean()) + 1 / 12
            cxy = float(((xs - xm) * (ys - ym)).mean())
            tr, det = cxx + cyy, cxx * cyy - cxy * cxy
            disc = math.sqrt(max(0.0, tr * tr / 4 - det))
            l1, l2 = tr / 2 + disc, max(tr / 2 - disc, 1e-9)
            if math.sqrt(l1 / l2) > self.max_elongation:
                return None, box
            if area / (4 * math.pi * math.sqrt(l1 * l2)) < self.min_fill:
                return None, box
        return sel, box

    def _colour(
        self,
        win: NDArray[np.uint8],
        ref: NDArray[np.uint8] | None,
        sel: NDArray[np.bool_],
        c: int,
    ) -> float | None:
        """Whether blob ``sel`` is of the laser's colour, by any of: its fringe (the other
        channels clip over at most ``fringe`` of it: a white or yellow patch clips them
        all over), its ring (:meth:`_ring_gain`), or, with the model ``ref``, the halo's
        rise (:meth:`_rise_ratio`). Returns a score (grey levels) or None."""
        a, b = (o for o in (0, 1, 2) if o != c)
        other_clipped = np.maximum(win[:, :, a], win[:, :, b])[sel] >= self.saturated
        fringe = float(np.mean(other_clipped))
        gain = self._ring_gain(win, sel, c)
        if gain is not None:
            return gain
        if fringe <= self.fringe and (
            self.fringe_ratio <= 0
            or ref is None
            or self._rise_ratio(win, ref, sel, c) >= self.fringe_ratio
        ):
            return self.halo * (1.0 + (self.fringe - fringe))
        if ref is not None and self._rise_ratio(win, ref, sel, c) >= self.colour_ratio:
            return self.halo
        return None

    def _rise_ratio(
        self, win: NDArray[np.uint8], ref: NDArray[np.uint8], sel: NDArray[np.bool_], c: int
    ) -> float:
        """In the halo (3 px around the blob, where the laser channel does not clip): the
        laser channel's rise over the model against the strongest other channel's, in
        linear light (gamma 2.2 assumed). A laser adds ``crosstalk`` (< 1/2) as much to
        the others; white or yellow content appearing adds about as much."""
        grown = cv2.dilate(sel.view(np.uint8), self._k7).view(bool)
        halo = grown & ~sel & (win[:, :, c] < self.saturated)
        if np.count_nonzero(halo) < 3:
            return 0.0
        now = _LIN[win[halo]]
        before = _LIN[ref[halo]]
        d = (now - before).clip(0.0)
        a, b = (o for o in (0, 1, 2) if o != c)
        rise_c = float(d[:, c].sum())
        rise_o = float(np.maximum(d[:, a], d[:, b]).sum())
        return rise_c / max(rise_o, 1e-4) if rise_c > 0.05 else 0.0

    def _ring_gain(self, win: NDArray[np.uint8], sel: NDArray[np.bool_], c: int) -> float | None:
        """How much more of the laser's colour the ring of pixels next to the blob is (the
        mean of its upper half) than the content around it (the median over a band
        ``r .. r + 4`` px outside, r the blob's radius but >= 4), in grey levels; None
        if it, or the ring's lift in the laser channel, is below ``halo``."""
        dist = cv2.distanceTransform((~sel).view(np.uint8), cv2.DIST_L2, 3)
        ring = (dist > 0) & (dist <= 1.5)
        r = max(4.0, math.sqrt(np.count_nonzero(sel) / math.pi))
        outer = (dist >= r) & (dist <= r + 4)
        if not ring.any() or not outer.any():
            return None
        wi = win.astype(np.int16)
        a, b = (o for o in (0, 1, 2) if o != c)
        excess = wi[:, :, c] - np.maximum(wi[:, :, a], wi[:, :, b])
        gain = _upper_mean(excess[ring]) - _median(excess[outer])
        lift = _upper_mean(wi[:, :, c][ring]) - _median(wi[:, :, c][outer])
        if gain < self.halo or lift < self.halo:
            return None
        return gain
