"""Tuning the One Euro filter of the camera-mouse cursor against rendered truth.

Pure numpy: arrays of cursor samples in, figures out (the plot is the only
output file, written by :func:`plot_tradeoff` when called). Conventions:

- ``t_s``: (N,) sample times in seconds, increasing (frame capture times).
- ``xy``: (N, 2) cursor, normalized screen coordinates as
  :class:`omnidev.screen.ScreenMapping` uses (``px = nx * (1920 - 1)``);
  a row of NaN is a frame for which the tracker gave no sample (the pipeline
  then holds the pointer and does not feed the filter).
- ``truth``: (N, 2) the true cursor (screen point under the image centre) in
  the same coordinates, finite on every row.
- Figures are in pixels of a 1920x1080 screen (:data:`SCREEN_PX`) and in ms.

Two measures of a still hand (trajectory "still" of :mod:`omnidev.sim.monitor`):

- ``step_rms_px``: RMS of the cursor's frame-to-frame movement (Euclidean, px
  per frame). This is the shake the user sees; it is the one the tuning bounds.
  The intended (slow sway) motion sets a floor, reported as the step RMS of
  the truth low-passed at :data:`STEADY_CUTOFF_HZ`.
- ``dev_rms_px``: RMS distance of the cursor from the truth low-passed at
  :data:`STEADY_CUTOFF_HZ` (zero phase): the tremor is part of the truth, but
  the user means the tremor-free aim; this also counts the filter's lag on
  the sway, so it is reported, not optimized.

One measure of a moving hand (trajectory "sweep", ~1 m/s of aim): the lag, the
time shift that best aligns the cursor with the truth (least squares over a
grid of shifts, truth interpolated linearly), and the RMS error at zero shift.

The tuning (:func:`grid_search`) picks the (min_cutoff, beta) of the grid with
the least sweep lag among those whose still-hand step RMS is at most a bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from omnidev.filters import OneEuroFilter

FloatArray = NDArray[np.float64]

SCREEN_PX = (1920, 1080)
STEADY_CUTOFF_HZ = 2.0  # the still hand's intended motion is below this
JITTER_BOUND_PX = 0.5  # px per frame at 30 fps: the still-hand step RMS the tuning allows


@dataclass(frozen=True)
class OneEuroParams:
    """One Euro filter parameters: cutoffs in Hz, ``beta`` in s per normalized screen unit."""

    min_cutoff: float
    beta: float
    d_cutoff: float = 1.0

    def make(self) -> OneEuroFilter:
        """A fresh :class:`~omnidev.filters.OneEuroFilter` with these parameters."""
        return OneEuroFilter(self.min_cutoff, self.beta, self.d_cutoff)


# The tuned defaults for the camera mouse: the pick of grid_search (grid
# DEFAULT_MIN_CUTOFFS x DEFAULT_BETAS x DEFAULT_D_CUTOFFS, bound JITTER_BOUND_PX)
# on 90 frames (30 fps, 640x480) of each of the "still" and "sweep" trajectories
# tracked by the camera-mouse plugin (homography), made by
#   OMNIDEV_TUNING_FRAMES=90 .venv/bin/python -m pytest -s tests/test_one_euro_tuning.py
# Figures there: still-hand step RMS 5.39 -> 0.48 px/frame, sweep lag 5.9 ms
# (the same pick with the tracker of commit 9f3d755 and with its later edits).
TUNED = OneEuroParams(min_cutoff=0.1, beta=20.0, d_cutoff=2.0)
DEFAULT_MIN_CUTOFFS = (0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0)
DEFAULT_BETAS = (0.0, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0, 50.0, 100.0)
DEFAULT_D_CUTOFFS = (1.0, 2.0, 4.0)


def _check(t_s: FloatArray, xy: FloatArray, name: str) -> tuple[FloatArray, FloatArray]:
    """``t_s`` (N,) and ``xy`` (N, 2) as float arrays, or ValueError naming ``name``."""
    t = np.asarray(t_s, np.float64)
    p = np.asarray(xy, np.float64)
    if t.ndim != 1 or p.shape != (len(t), 2):
        raise ValueError(f"{name}: expected t (N,) and xy (N, 2), got {t.shape} and {p.shape}")
    if len(t) > 1 and not np.all(np.diff(t) > 0):
        raise ValueError(f"{name}: times must increase")
    return t, p


def to_px(xy: FloatArray) -> FloatArray:
    """Normalized screen (N, 2) -> pixels of the 1920x1080 screen (N, 2)."""
    out: FloatArray = np.asarray(xy, np.float64) * np.array([SCREEN_PX[0] - 1, SCREEN_PX[1] - 1])
    return out


def filter_cursor(t_s: FloatArray, xy: FloatArray, params: OneEuroParams | None) -> FloatArray:
    """The cursor after the One Euro filter (N, 2), normalized; ``None``: unfiltered.

    Rows without a sample (NaN) are skipped, as the pipeline does, and stay NaN.
    """
    t, p = _check(t_s, xy, "filter_cursor")
    if params is None:
        return p.copy()
    filt = params.make()
    out = np.full_like(p, np.nan)
    for i in np.flatnonzero(np.all(np.isfinite(p), axis=1)):
        out[i] = filt(float(t[i]), p[i])
    return out


def lowpass_zero_phase(t_s: FloatArray, xy: FloatArray, cutoff_hz: float) -> FloatArray:
    """Zero-phase Gaussian low-pass of evenly sampled ``xy`` (N, 2), -3 dB at ``cutoff_hz``.

    The Gaussian's amplitude response exp(-(2 pi f sigma)^2 / 2) is 1/sqrt(2) at
    ``cutoff_hz`` for sigma = sqrt(ln 2) / (2 pi cutoff_hz); near the ends the
    kernel is cut and renormalized.
    """
    t, p = _check(t_s, xy, "lowpass_zero_phase")
    if len(t) < 2:
        return p.copy()
    dt = float(np.median(np.diff(t)))
    sigma = math.sqrt(math.log(2.0)) / (2 * math.pi * cutoff_hz) / dt  # samples
    half = max(1, math.ceil(4 * sigma))
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
    ones = np.convolve(np.ones(len(t)), k, mode="same")
    out = np.stack([np.convolve(p[:, j], k, mode="same") / ones for j in range(2)], axis=1)
    return out


@dataclass(frozen=True)
class StillFigures:
    """Still-hand figures (px of a 1920x1080 screen; steps per frame)."""

    step_rms_px: float  # RMS frame-to-frame movement of the cursor (bounded by the tuning)
    dev_rms_px: float  # RMS distance from the truth low-passed at STEADY_CUTOFF_HZ
    truth_step_rms_px: float  # the same step RMS of the low-passed truth (intended motion)
    samples: int  # frames with a sample


def still_figures(t_s: FloatArray, cursor: FloatArray, truth: FloatArray) -> StillFigures:
    """:class:`StillFigures` of a (filtered or raw) ``cursor`` against ``truth``.

    Steps are taken between consecutive frames that both have a sample.
    """
    t, c = _check(t_s, cursor, "still_figures cursor")
    _, tr = _check(t_s, truth, "still_figures truth")
    smooth = to_px(lowpass_zero_phase(t, tr, STEADY_CUTOFF_HZ))
    cp = to_px(c)
    ok = np.all(np.isfinite(cp), axis=1)
    steps = np.linalg.norm(np.diff(cp, axis=0), axis=1)[ok[1:] & ok[:-1]]
    dev = np.linalg.norm(cp[ok] - smooth[ok], axis=1)
    truth_steps = np.linalg.norm(np.diff(smooth, axis=0), axis=1)
    return StillFigures(
        step_rms_px=float(np.sqrt(np.mean(steps**2))) if len(steps) else math.nan,
        dev_rms_px=float(np.sqrt(np.mean(dev**2))) if len(dev) else math.nan,
        truth_step_rms_px=float(np.sqrt(np.mean(truth_steps**2))),
        samples=int(ok.sum()),
    )


@dataclass(frozen=True)
class SweepFigures:
    """Moving-hand figures."""

    lag_ms: float  # the time shift best aligning cursor(t) with truth(t - lag)
    rms_px: float  # RMS distance from the truth at zero shift (px, 1920x1080)
    rms_shifted_px: float  # the same after removing the lag
    samples: int  # frames with a sample that enter the figures


def sweep_figures(
    t_s: FloatArray,
    cursor: FloatArray,
    truth: FloatArray,
    *,
    max_lag_s: float = 0.25,
    step_s: float = 0.001,
) -> SweepFigures:
    """:class:`SweepFigures`: lag by least squares over shifts 0..``max_lag_s``.

    For each shift, the truth at ``t - shift`` (linear interpolation of the
    truth samples) is compared with the cursor at ``t`` on the same frames
    (those with a sample and ``t - max_lag_s >= t[0]``); the lag is the shift
    of least mean squared distance, refined by a parabola through its
    neighbours. Negative shifts down to ``-max_lag_s / 5`` are allowed so that
    an unfiltered cursor measures ~0 rather than sticking to the bound. A lag
    of ``max_lag_s`` means "at least that much" (e.g. beta = 0 at a low
    min_cutoff).
    """
    t, c = _check(t_s, cursor, "sweep_figures cursor")
    _, tr = _check(t_s, truth, "sweep_figures truth")
    cp, tp = to_px(c), to_px(tr)
    use = np.all(np.isfinite(cp), axis=1) & (t - max_lag_s >= t[0]) & (t + max_lag_s / 5 <= t[-1])
    if use.sum() < 3:
        raise ValueError("sweep_figures: too few samples for the lag fit")
    shifts = np.arange(-max_lag_s / 5, max_lag_s + step_s / 2, step_s)
    tu = t[use]
    mse = np.empty(len(shifts))
    for k, s in enumerate(shifts):
        ref = np.stack([np.interp(tu - s, t, tp[:, j]) for j in range(2)], axis=1)
        mse[k] = float(np.mean(np.sum((cp[use] - ref) ** 2, axis=1)))
    k = int(np.argmin(mse))
    lag = float(shifts[k])
    if 0 < k < len(shifts) - 1:
        a, b, cc = mse[k - 1], mse[k], mse[k + 1]
        den = a - 2 * b + cc
        if den > 0:
            lag += 0.5 * (a - cc) / den * step_s
    zero = np.sum((cp[use] - tp[use]) ** 2, axis=1)
    return SweepFigures(
        lag_ms=1000.0 * lag,
        rms_px=float(np.sqrt(np.mean(zero))),
        rms_shifted_px=float(np.sqrt(mse[k])),
        samples=int(use.sum()),
    )


@dataclass(frozen=True)
class Recording:
    """Raw tracker samples of one trajectory with their truth (see the module docstring)."""

    t_s: FloatArray
    raw: FloatArray
    truth: FloatArray


@dataclass(frozen=True)
class Evaluation:
    """The figures of one parameter set (None: unfiltered) on the still and sweep recordings."""

    params: OneEuroParams | None
    still: StillFigures
    sweep: SweepFigures


def evaluate(params: OneEuroParams | None, still: Recording, sweep: Recording) -> Evaluation:
    """Filter both recordings with ``params`` and measure them."""
    fs = filter_cursor(still.t_s, still.raw, params)
    fw = filter_cursor(sweep.t_s, sweep.raw, params)
    return Evaluation(
        params,
        still_figures(still.t_s, fs, still.truth),
        sweep_figures(sweep.t_s, fw, sweep.truth),
    )


@dataclass(frozen=True)
class GridResult:
    """A grid search: every point's evaluation, the unfiltered one, the bound and the pick."""

    points: list[Evaluation]
    unfiltered: Evaluation
    jitter_bound_px: float
    best: Evaluation | None  # None when no point meets the bound


def grid_search(
    still: Recording,
    sweep: Recording,
    *,
    min_cutoffs: tuple[float, ...] = DEFAULT_MIN_CUTOFFS,
    betas: tuple[float, ...] = DEFAULT_BETAS,
    d_cutoffs: tuple[float, ...] = DEFAULT_D_CUTOFFS,
    jitter_bound_px: float = JITTER_BOUND_PX,
) -> GridResult:
    """Evaluate every (min_cutoff, beta, d_cutoff); pick the least sweep lag among
    those with still-hand step RMS <= ``jitter_bound_px``.

    Ties in lag (within 1 ms) go to the smaller sweep RMS error.
    """
    points = [
        evaluate(OneEuroParams(mc, b, dc), still, sweep)
        for dc in d_cutoffs
        for mc in min_cutoffs
        for b in betas
    ]
    ok = [p for p in points if p.still.step_rms_px <= jitter_bound_px]
    best = None
    if ok:
        least = min(p.sweep.lag_ms for p in ok)
        best = min((p for p in ok if p.sweep.lag_ms <= least + 1.0), key=lambda p: p.sweep.rms_px)
    return GridResult(points, evaluate(None, still, sweep), jitter_bound_px, best)


def plot_tradeoff(result: GridResult, path: Path) -> None:
    """Write a PNG: still-hand step RMS (px per frame) against sweep lag (ms) for the grid.

    Lines: one per min_cutoff through its betas, at the chosen d_cutoff (the
    first of the grid if none was chosen); grey dots: the other d_cutoffs. The
    unfiltered cursor, the bound and the chosen point are marked.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grid = [p for p in result.points if p.params is not None]
    if not grid:
        raise ValueError("plot_tradeoff: the grid is empty")
    best = result.best.params if result.best is not None else None
    dc = best.d_cutoff if best is not None else grid[0].params.d_cutoff  # type: ignore[union-attr]
    fig, ax = plt.subplots(figsize=(8, 5.5))
    others = [p for p in grid if p.params is not None and p.params.d_cutoff != dc]
    if others:
        ax.plot(
            [p.sweep.lag_ms for p in others],
            [p.still.step_rms_px for p in others],
            ".",
            color="0.7",
            ms=4,
            label="other d_cutoff",
        )
    cutoffs = sorted({p.params.min_cutoff for p in grid if p.params is not None})
    for mc in cutoffs:
        row = [
            p
            for p in grid
            if p.params is not None and p.params.min_cutoff == mc and p.params.d_cutoff == dc
        ]
        ax.plot(
            [p.sweep.lag_ms for p in row],
            [p.still.step_rms_px for p in row],
            ".-",
            lw=0.8,
            label=f"min_cutoff {mc:g} Hz",
        )
    u = result.unfiltered
    ax.plot(u.sweep.lag_ms, u.still.step_rms_px, "kx", ms=10, mew=2, label="unfiltered")
    ax.axhline(result.jitter_bound_px, color="r", lw=0.8, ls="--", label="jitter bound")
    if result.best is not None and best is not None:
        b = result.best
        ax.plot(
            b.sweep.lag_ms,
            b.still.step_rms_px,
            "o",
            ms=14,
            mfc="none",
            mec="r",
            mew=2,
            label=f"chosen: {best.min_cutoff:g} Hz, beta {best.beta:g}, d_cutoff {best.d_cutoff:g}",
        )
    ax.set_xscale("log")  # lags below 0.5 ms (none in practice) would fall off the left
    ax.set_xlim(left=0.5)
    ax.set_yscale("log")
    ticks = [1, 2, 5, 10, 20, 50, 100, 200]
    ax.set_xticks(ticks, [str(v) for v in ticks])
    ax.set_xlabel("sweep lag (ms)")
    ax.set_ylabel("still hand: RMS cursor step per frame (px, 1920x1080, 30 fps)")
    ax.set_title(
        f"One Euro filter on the camera-mouse cursor "
        f"(lines: d_cutoff {dc:g} Hz; beta rises leftwards)",
        fontsize=10,
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
