"""``record`` sink: every event as one JSON line, for tests and for replaying.

Lines (``t_ns`` is the monotonic clock, ns):

    {"t_ns": ..., "kind": "open", "screen": [x, y, w, h], "layout": [w, h]}
    {"t_ns": ..., "kind": "move", "x": 0.25, "y": 0.5, "pixel": [px, py]}
    {"t_ns": ..., "kind": "button", "button": "left", "down": true}
    {"t_ns": ..., "kind": "close"}

``x``/``y`` are the clamped normalized position, ``pixel`` the layout pixel;
a move made from a tracker's sample also has ``capture_ns``, the capture time
of the frame it came from.
Each line is flushed as it is written, so a crash loses nothing before it.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any

from omnidev.errors import SinkError
from omnidev.screen import ScreenMapping
from omnidev.sinks.base import BUTTONS, PointerSink


class RecordSink(PointerSink):
    """Writes JSON lines to a file (``path``) or to standard output (``path = "-"``)."""

    name = "record"

    def __init__(self, path: str, mapping: ScreenMapping) -> None:
        super().__init__(mapping)
        self.path = path
        try:
            self._fh: IO[str] = (
                sys.stdout if path == "-" else open(path, "a", encoding="utf-8")  # noqa: SIM115
            )
        except OSError as exc:
            raise SinkError(f"record sink: cannot open {path}: {exc.strerror}") from None
        s = mapping.screen
        self._write(
            kind="open",
            screen=[s.x, s.y, s.width, s.height],
            layout=[mapping.layout_width, mapping.layout_height],
        )

    def _write(self, **fields: Any) -> None:
        line = json.dumps({"t_ns": time.monotonic_ns(), **fields}, separators=(",", ":"))
        try:
            self._fh.write(line + "\n")
            self._fh.flush()
        except OSError as exc:
            raise SinkError(f"record sink: writing {self.path}: {exc.strerror}") from None

    def _move(self, nx: float, ny: float) -> None:
        extra = {} if self.capture_ns is None else {"capture_ns": self.capture_ns}
        self._write(kind="move", x=nx, y=ny, pixel=list(self.mapping.to_pixel(nx, ny)), **extra)

    def _button(self, button: str, down: bool) -> None:
        self._write(kind="button", button=button, down=down)

    def _close(self) -> None:
        self._write(kind="close")
        if self._fh is not sys.stdout:
            self._fh.close()


def open_record(options: Mapping[str, Any], mapping: ScreenMapping) -> RecordSink:
    """Entry point: options ``path`` (a file, appended to; ``-`` for stdout)."""
    unknown = set(options) - {"path"}
    if unknown:
        raise SinkError(f"record sink: unknown option {sorted(unknown)[0]!r} (options: path)")
    path = options.get("path")
    if not isinstance(path, str) or not path:
        raise SinkError("record sink: option 'path' (a file, or - for stdout) is required")
    return RecordSink(path, mapping)


def read_events(path: str | Path) -> Iterator[dict[str, Any]]:
    """The events of a recording, checked line by line."""
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                event = json.loads(line)
            except json.JSONDecodeError as exc:
                raise SinkError(f"{path}: line {lineno}: not JSON ({exc.msg})") from None
            kind = event.get("kind") if isinstance(event, dict) else None
            if kind not in ("open", "move", "button", "close") or "t_ns" not in event:
                raise SinkError(f"{path}: line {lineno}: not a pointer event")
            if kind == "button" and event.get("button") not in BUTTONS:
                raise SinkError(f"{path}: line {lineno}: unknown button {event.get('button')!r}")
            yield event


def replay(path: str | Path, sink: PointerSink, *, realtime: bool = True) -> int:
    """Send a recording's moves and buttons to ``sink``; returns the events sent.

    With ``realtime`` the original spacing between events is kept. Buttons still
    down at the end are released (the sink's close does it too).
    """
    sent = 0
    t0_rec: int | None = None
    t0 = time.monotonic_ns()
    for event in read_events(path):
        if event["kind"] not in ("move", "button"):
            continue
        if realtime:
            t0_rec = event["t_ns"] if t0_rec is None else t0_rec
            delay = (event["t_ns"] - t0_rec) - (time.monotonic_ns() - t0)
            if delay > 0:
                time.sleep(delay / 1e9)
        if event["kind"] == "move":
            sink.move(float(event["x"]), float(event["y"]))
        elif event["down"]:
            sink.press(event["button"])
        else:
            sink.release(event["button"])
        sent += 1
    sink.release_all()
    return sent
