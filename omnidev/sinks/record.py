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
import math
import os
import sys
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any

from omnidev.errors import SinkError
from omnidev.inputfile import loads_json, read_text
from omnidev.screen import ScreenMapping
from omnidev.sinks.base import BUTTONS, PointerSink

MAX_PAUSE_S = 5.0
"""Longest pause a realtime replay keeps between two events, s."""


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


def _record_path(options: Mapping[str, Any]) -> str:
    unknown = set(options) - {"path"}
    if unknown:
        raise SinkError(f"record sink: unknown option {sorted(unknown)[0]!r} (options: path)")
    path = options.get("path")
    if not isinstance(path, str) or not path or "\0" in path:
        raise SinkError("record sink: option 'path' (a file, or - for stdout) is required")
    return path


def open_record(options: Mapping[str, Any], mapping: ScreenMapping) -> RecordSink:
    """Entry point: options ``path`` (a file, appended to; ``-`` for stdout)."""
    return RecordSink(_record_path(options), mapping)


def check_record(options: Mapping[str, Any], mapping: ScreenMapping) -> str:
    """What ``omnidev daemon --check`` checks: the options, and that ``path`` can be appended
    to (its folder exists and is writable, it is not a folder); nothing is written."""
    path = _record_path(options)
    if path == "-":
        return "record: JSON lines to standard output"
    p = Path(path)
    if p.is_dir():
        raise SinkError(f"record sink: path {path} is a folder; give a file name")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise SinkError(f"record sink: path {path}: folder {parent} does not exist")
    writable = os.access(p, os.W_OK) if p.exists() else os.access(parent, os.W_OK | os.X_OK)
    if not writable:
        raise SinkError(f"record sink: path {path} is not writable by this user")
    return f"record: appends JSON lines to {path}"


open_record.check = check_record  # type: ignore[attr-defined]


def read_events(path: str | Path) -> Iterator[dict[str, Any]]:
    """The events of a recording, checked line by line: every field a replay uses is there
    and of its type (``t_ns`` an integer; a move's ``x``, ``y`` finite numbers; a button's
    ``button`` one of :data:`BUTTONS` and ``down`` true/false)."""
    text = read_text(path, "pointer recording (JSON lines)", error=SinkError)
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        where = f"{path}: line {lineno}"
        event = loads_json(line, where, "pointer event", SinkError)
        kind = event.get("kind") if isinstance(event, dict) else None
        if kind not in ("open", "move", "button", "close"):
            raise SinkError(f"{where}: not a pointer event (kind open, move, button or close)")
        t = event.get("t_ns")
        if isinstance(t, bool) or not isinstance(t, int):
            raise SinkError(f"{where}: t_ns must be an integer time in ns, got {t!r}")
        if kind == "move":
            for key in ("x", "y"):
                v = event.get(key)
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                    raise SinkError(f"{where}: move {key} must be a finite number, got {v!r}")
        if kind == "button":
            if event.get("button") not in BUTTONS:
                raise SinkError(f"{where}: unknown button {event.get('button')!r}")
            if not isinstance(event.get("down"), bool):
                raise SinkError(f"{where}: button down must be true or false")
        yield event


def replay(path: str | Path, sink: PointerSink, *, realtime: bool = True) -> int:
    """Send a recording's moves and buttons to ``sink``; returns the events sent.

    With ``realtime`` the original spacing between events is kept, except that a pause
    longer than :data:`MAX_PAUSE_S` is cut to that (a recording that sat idle, or a
    clock jump, does not freeze the replay). Buttons still down at the end are released
    (the sink's close does it too).
    """
    sent = 0
    last_rec: int | None = None
    due = time.monotonic_ns()
    for event in read_events(path):
        if event["kind"] not in ("move", "button"):
            continue
        if realtime:
            gap = 0 if last_rec is None else event["t_ns"] - last_rec
            last_rec = event["t_ns"]
            due += min(max(gap, 0), int(MAX_PAUSE_S * 1e9))
            delay = due - time.monotonic_ns()
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
