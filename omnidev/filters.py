"""Pointer smoothing: the One Euro filter (Casiez, Roussel, Vogel, CHI 2012).

An adaptive low-pass filter: its cutoff rises with the signal's speed, so a
still hand gives a steady cursor (low cutoff: little jitter) and a fast sweep
little lag (high cutoff). Times in seconds, values in any unit (here normalized
screen coordinates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


def smoothing_factor(dt: float, cutoff: float) -> float:
    """alpha of an exponential smoother with cutoff frequency ``cutoff`` Hz at step ``dt`` s."""
    tau = 1.0 / (2.0 * math.pi * cutoff)
    return 1.0 / (1.0 + tau / dt)


@dataclass
class OneEuroFilter:
    """One Euro filter over a vector of values.

    Attributes:
        min_cutoff: Hz, the cutoff when the signal is still (lower: steadier).
        beta: s/unit, how much the cutoff rises with speed (higher: less lag).
        d_cutoff: Hz, the cutoff of the speed estimate itself.
        max_gap_s: s; a value observed longer than this after the previous one starts
            the filter afresh (positions many frames apart are not blended, e.g. a
            laser spot found again elsewhere). None: never (the original filter).
    """

    min_cutoff: float = 1.0
    beta: float = 0.007
    d_cutoff: float = 1.0
    max_gap_s: float | None = None

    def __post_init__(self) -> None:
        for key in ("min_cutoff", "beta", "d_cutoff"):
            value = getattr(self, key)
            if not math.isfinite(value) or value < 0 or (key != "beta" and value == 0):
                raise ValueError(f"one-euro {key} must be a positive number, got {value}")
        gap = self.max_gap_s
        if gap is not None and (not math.isfinite(gap) or gap <= 0):
            raise ValueError(f"one-euro max_gap_s must be a positive number of seconds, got {gap}")
        self.reset()

    def reset(self) -> None:
        """Forget the past (e.g. after the tracker lost its target)."""
        self._t: float | None = None
        self._x: NDArray[np.float64] = np.zeros(0)
        self._dx: NDArray[np.float64] = np.zeros(0)

    def __call__(self, t: float, x: NDArray[np.float64] | list[float]) -> NDArray[np.float64]:
        """Filtered value of ``x`` observed at time ``t`` (s, increasing)."""
        value = np.asarray(x, np.float64)
        if self._t is None or value.shape != self._x.shape:
            self._t, self._x, self._dx = t, value.copy(), np.zeros_like(value)
            return value.copy()
        dt = t - self._t
        if self.max_gap_s is not None and dt > self.max_gap_s:
            self._t, self._x, self._dx = t, value.copy(), np.zeros_like(value)
            return value.copy()
        if dt <= 0:  # same or older timestamp: nothing new to learn from
            return self._x.copy()
        a_d = smoothing_factor(dt, self.d_cutoff)
        self._dx = a_d * (value - self._x) / dt + (1 - a_d) * self._dx
        cutoff = self.min_cutoff + self.beta * np.abs(self._dx)
        tau = 1.0 / (2.0 * np.pi * cutoff)
        a = 1.0 / (1.0 + tau / dt)
        self._x = a * value + (1 - a) * self._x
        self._t = t
        return self._x.copy()
