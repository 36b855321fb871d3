"""Dwell click: a click when the cursor rests in one place (pure: no devices).

The cursor is followed in screen pixels (any frame whose unit is the pixel, e.g.
the layout pixels of :mod:`omnidev.screen`), with times in seconds on one
monotonic clock. Where the cursor *settles* is the first position after it last
left the rest circle (or after a :meth:`DwellClicker.reset`); the click fires once
the cursor has stayed within ``radius_px`` of that anchor for ``dwell_s``. It
fires once per rest: it re-arms only when the cursor leaves the circle, which
also anchors a new rest at the position outside it.

Example:
    >>> d = DwellClicker(radius_px=10.0, dwell_s=0.5)
    >>> [d.update(t / 10, 100.0 + t % 3, 200.0) for t in range(8)]
    [False, False, False, False, False, True, False, False]
    >>> d.update(0.8, 150.0, 200.0)  # left the circle: re-armed, a new rest begins
    False
"""

from __future__ import annotations

import math

BUTTONS = ("left", "right", "middle")


class DwellClicker:
    """Fires one click when the cursor has rested ``dwell_s`` within ``radius_px``.

    Args:
        radius_px: radius of the rest circle around the anchor, screen pixels (> 0).
        dwell_s: how long the cursor must stay inside it, seconds (> 0).
        button: the pointer button the click is for: ``left``, ``right`` or ``middle``
            (only carried for the caller, which presses and releases it).
    """

    def __init__(self, radius_px: float = 12.0, dwell_s: float = 0.8, button: str = "left") -> None:
        if not (isinstance(radius_px, int | float) and math.isfinite(radius_px) and radius_px > 0):
            raise ValueError(
                f"dwell click: radius_px must be a finite number > 0, got {radius_px!r}"
            )
        if not (isinstance(dwell_s, int | float) and math.isfinite(dwell_s) and dwell_s > 0):
            raise ValueError(f"dwell click: dwell_s must be a finite number > 0 s, got {dwell_s!r}")
        if button not in BUTTONS:
            raise ValueError(
                f"dwell click: button must be one of {', '.join(BUTTONS)}, got {button!r}"
            )
        self.radius_px = float(radius_px)
        self.dwell_s = float(dwell_s)
        self.button = button
        self._anchor: tuple[float, float, float] | None = None  # x px, y px, t s
        self._fired = False
        self._last_t: float | None = None

    def update(self, t_s: float, x_px: float, y_px: float) -> bool:
        """Feed the cursor at time ``t_s`` (s) and position (``x_px``, ``y_px``) (screen px).

        Returns:
            True exactly once per rest: on the first update at which the cursor has
            stayed within ``radius_px`` of its anchor for at least ``dwell_s``.

        A non-finite position counts as tracking lost (:meth:`reset`). Raises
        ValueError when ``t_s`` is not finite or goes back in time.
        """
        if not math.isfinite(t_s):
            raise ValueError(f"dwell click: time must be finite, got {t_s!r}")
        if self._last_t is not None and t_s < self._last_t:
            raise ValueError(
                f"dwell click: time went back from {self._last_t} s to {t_s} s "
                "(use one monotonic clock)"
            )
        self._last_t = t_s
        if not (math.isfinite(x_px) and math.isfinite(y_px)):
            self.reset()
            return False
        if (
            self._anchor is None
            or math.hypot(x_px - self._anchor[0], y_px - self._anchor[1]) > self.radius_px
        ):
            self._anchor = (x_px, y_px, t_s)
            self._fired = False
            return False
        if not self._fired and t_s - self._anchor[2] >= self.dwell_s:
            self._fired = True
            return True
        return False

    def progress(self, t_s: float) -> float:
        """How far the current rest is towards a click at ``t_s``: 0 .. 1 (1 once fired)."""
        if self._anchor is None:
            return 0.0
        if self._fired:
            return 1.0
        return min(1.0, max(0.0, (t_s - self._anchor[2]) / self.dwell_s))

    def reset(self) -> None:
        """Forget the rest (tracking lost): the next position starts a new one, armed."""
        self._anchor = None
        self._fired = False
        self._last_t = None
