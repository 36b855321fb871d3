"""The :class:`PointerSink` contract and its safety rules.

A sink receives positions normalized to the target screen and button changes,
and turns them into events of one OS interface. The base class does what every
sink must do the same way: clamp coordinates into range, map them through the
:class:`~omnidev.screen.ScreenMapping`, remember which buttons are down, and
release every one of them on :meth:`PointerSink.close`, when a ``with`` block
ends by an exception, and (with :func:`release_on_signals`) on SIGTERM/SIGINT.
"""

from __future__ import annotations

import logging
import signal
import time
from abc import ABC, abstractmethod
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from types import FrameType, TracebackType
from typing import Any

from omnidev.errors import SinkError
from omnidev.frame import PointerSample
from omnidev.screen import ScreenMapping, clamp01

BUTTONS = ("left", "right", "middle")
log = logging.getLogger("omnidev.sinks")


class PointerSink(ABC):
    """An absolute pointer with three buttons.

    Subclasses implement :meth:`_move`, :meth:`_button` and :meth:`_close`;
    :meth:`_flush` ends one report when the interface batches events.

    Attributes:
        name: the sink's plugin name.
        mapping: where the normalized screen lies in the desktop layout.
        pressed: the buttons currently held down.
        events: count of move and button events handed to the OS.
    """

    name = "sink"

    def __init__(self, mapping: ScreenMapping) -> None:
        self.mapping = mapping
        self.pressed: set[str] = set()
        self.events = 0
        self.closed = False
        self.last_position: tuple[float, float] | None = None
        # the frame of the sample being emitted (its timestamp_ns and index), for sinks
        # that log it; None outside emit() and click(sample=...)
        self.frame_ns: int | None = None
        self.frame_index: int | None = None

    # -- what subclasses provide -------------------------------------------------
    @abstractmethod
    def _move(self, nx: float, ny: float) -> None:
        """Move to the clamped normalized position (map it with ``self.mapping``)."""

    @abstractmethod
    def _button(self, button: str, down: bool) -> None:
        """Press (``down``) or release one of :data:`BUTTONS`."""

    def _flush(self) -> None:  # noqa: B027 - optional hook, most sinks need none
        """End the current report (after a move and its button changes)."""

    @abstractmethod
    def _close(self) -> None:
        """Release the OS resource. Buttons are already released."""

    # -- the public API ----------------------------------------------------------
    def move(self, x: float, y: float) -> None:
        """Move the pointer to normalized (x, y); values outside [0, 1] are clamped."""
        self._check_open()
        nx, ny = clamp01(x), clamp01(y)
        self._move(nx, ny)
        self._flush()
        self.last_position = (nx, ny)
        self.events += 1

    def press(self, button: str) -> None:
        """Press ``button`` (no-op when it is already down)."""
        self._set_button(button, True)
        self._flush()

    def release(self, button: str) -> None:
        """Release ``button`` (no-op when it is up)."""
        self._set_button(button, False)
        self._flush()

    def click(self, button: str = "left", *, sample: PointerSample | None = None) -> None:
        """Press and release. ``sample``: the pointer sample the click comes from (a
        dwell click), so a sink that logs frames names its frame."""
        if sample is not None:
            self.frame_ns, self.frame_index = sample.timestamp_ns, sample.frame_index
        try:
            self.press(button)
            self.release(button)
        finally:
            if sample is not None:
                self.frame_ns = self.frame_index = None

    def emit(self, sample: PointerSample) -> None:
        """Move to the sample's position and make the buttons match its ``buttons``."""
        self._check_open()
        nx, ny = clamp01(sample.x), clamp01(sample.y)
        self.frame_ns, self.frame_index = sample.timestamp_ns, sample.frame_index
        try:
            self._move(nx, ny)
            self.last_position = (nx, ny)
            self.events += 1
            for b in BUTTONS:
                want = b in sample.buttons
                if want != (b in self.pressed):
                    self._set_button(b, want)
            self._flush()
        finally:
            self.frame_ns = self.frame_index = None

    def release_all(self) -> None:
        """Release every button that is down; errors on one do not stop the others."""
        first: Exception | None = None
        for b in sorted(self.pressed):
            try:
                self._button(b, False)
            except Exception as exc:  # keep releasing the rest
                first = first or exc
            self.pressed.discard(b)
        try:
            self._flush()
        except Exception as exc:
            first = first or exc
        if first is not None:
            raise SinkError(f"{self.name}: releasing buttons failed: {first}") from first

    def close(self) -> None:
        """Release every button, then the OS resource. Safe to call twice."""
        if self.closed:
            return
        try:
            self.release_all()
        finally:
            self.closed = True
            self._close()

    def stats(self) -> dict[str, Any]:
        """Counters for status reports."""
        return {"sink": self.name, "events": self.events, "pressed": sorted(self.pressed)}

    def __enter__(self) -> PointerSink:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __del__(self) -> None:
        # Last resort only; close() is the contract.
        if not getattr(self, "closed", True) and getattr(self, "pressed", None):
            with suppress(Exception):
                self.close()

    # -- helpers -----------------------------------------------------------------
    def _set_button(self, button: str, down: bool) -> None:
        self._check_open()
        if button not in BUTTONS:
            raise SinkError(
                f"{self.name}: unknown button {button!r} (buttons: left, right, middle)"
            )
        if down == (button in self.pressed):
            return
        self._button(button, down)
        if down:
            self.pressed.add(button)
        else:
            self.pressed.discard(button)
        self.events += 1

    def _check_open(self) -> None:
        if self.closed:
            raise SinkError(f"{self.name}: sink is closed")


def now_ns() -> int:
    """The monotonic clock every capture timestamp uses, ns."""
    return time.monotonic_ns()


@contextmanager
def release_on_signals(*sinks: PointerSink) -> Iterator[None]:
    """Turn SIGTERM and SIGINT into a clean exit that releases the sinks' buttons.

    Inside the block a SIGTERM raises :class:`SystemExit` (SIGINT keeps raising
    :class:`KeyboardInterrupt`); either way the sinks are closed on the way out,
    which releases every pressed button. Main thread only (Python's rule for
    signal handlers).
    """

    def on_term(signum: int, frame: FrameType | None) -> None:
        raise SystemExit(128 + signum)

    old_term = signal.signal(signal.SIGTERM, on_term)
    old_int = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old_term)
        signal.signal(signal.SIGINT, old_int)
        for sink in sinks:
            try:
                sink.close()
            except Exception:
                log.exception("closing sink %s", sink.name)
