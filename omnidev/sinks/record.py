"""``record`` sink: every event as one JSON line, for tests and for replaying.

Lines (format 2; ``t_ns`` is the monotonic time the line was written, ns):

    {"t_ns": ..., "kind": "open", "format": 2, "screen": [x, y, w, h], "layout": [w, h]}
    {"t_ns": ..., "kind": "move", "x": 0.25, "y": 0.5, "pixel": [px, py],
     "frame": 17, "frame_ns": 283333333}
    {"t_ns": ..., "kind": "button", "button": "left", "down": true, "frame": 17, "frame_ns": ...}
    {"t_ns": ..., "kind": "close"}

``x``/``y`` are the clamped normalized position, ``pixel`` the layout pixel.
A move or button made from a tracker's sample also has ``frame``, the index of
the frame it came from, and ``frame_ns``, that frame's timestamp (a camera's:
its capture time on the monotonic clock, as ``t_ns``; a file's: its presentation
time from the start of the file), so samples can be matched to frames and a
recording of a file replays at the video's own pace. ``frame`` is absent when
the pipeline did not say (a tracker used directly). Format 1 (no ``format`` key)
had ``capture_ns`` instead and no frame index; it is still read.
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
from typing import IO, Any, Literal

from omnidev.errors import SinkError
from omnidev.inputfile import loads_json, read_text
from omnidev.screen import ScreenMapping
from omnidev.sinks.base import BUTTONS, PointerSink

FORMAT = 2
FORMATS_READ = (1, 2)
Timing = Literal["frames", "written"]
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
            format=FORMAT,
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

    def _frame_fields(self) -> dict[str, int]:
        out: dict[str, int] = {}
        if self.frame_index is not None:
            out["frame"] = self.frame_index
        if self.frame_ns is not None:
            out["frame_ns"] = self.frame_ns
        return out

    def _move(self, nx: float, ny: float) -> None:
        pixel = list(self.mapping.to_pixel(nx, ny))
        self._write(kind="move", x=nx, y=ny, pixel=pixel, **self._frame_fields())

    def _button(self, button: str, down: bool) -> None:
        self._write(kind="button", button=button, down=down, **self._frame_fields())

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


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _check_event(event: dict[str, Any], where: str) -> None:
    """Raise a :class:`SinkError` naming ``where`` (file and line) for a malformed event."""
    kind = event["kind"]
    if not _is_int(event.get("t_ns")):
        raise SinkError(f"{where}: t_ns must be an integer (ns)")
    if kind == "open" and "format" in event and event["format"] not in FORMATS_READ:
        known = ", ".join(map(str, FORMATS_READ))
        raise SinkError(
            f"{where}: recording format {event['format']!r} is not one this omnidev reads "
            f"({known}); a newer omnidev wrote it?"
        )
    if kind == "move":
        for key in ("x", "y"):
            value = event.get(key)
            if not isinstance(value, int | float) or isinstance(value, bool):
                raise SinkError(f"{where}: {key} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise SinkError(f"{where}: {key} must be finite, got {value!r}")
    if kind == "button":
        if event.get("button") not in BUTTONS:
            raise SinkError(f"{where}: unknown button {event.get('button')!r}")
        if not isinstance(event.get("down"), bool):
            raise SinkError(f"{where}: down must be true or false, got {event.get('down')!r}")
    if kind in ("move", "button"):
        for key in ("frame", "frame_ns", "capture_ns"):
            if key in event and not _is_int(event[key]):
                raise SinkError(f"{where}: {key} must be an integer, got {event[key]!r}")
        if "frame" in event and event["frame"] < 0:
            raise SinkError(f"{where}: frame must be >= 0, got {event['frame']}")


def read_events(path: str | Path) -> Iterator[dict[str, Any]]:
    """The events of a recording (format 1 or 2), checked line by line: every field a
    replay uses is there and of its type (:func:`_check_event`).

    A malformed line raises a :class:`SinkError` naming the file and line; the file is
    read through :func:`omnidev.inputfile.read_text` (no folders, devices, huge files or
    non-UTF-8 bytes).
    """
    text = read_text(path, "pointer recording (JSON lines)", error=SinkError)
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        where = f"{path}: line {lineno}"
        event = loads_json(line, where, "pointer event", SinkError)
        kind = event.get("kind") if isinstance(event, dict) else None
        if kind not in ("open", "move", "button", "close") or "t_ns" not in event:
            raise SinkError(f"{where}: not a pointer event (kind open, move, button or close)")
        _check_event(event, where)
        yield event


def schedule_ns(events: list[dict[str, Any]], timing: Timing = "frames") -> list[int]:
    """When to send each event, ns after the first, for a replay at the original pace.

    ``timing="written"``: the spacing of the lines' ``t_ns``. ``"frames"``: events
    that carry a ``frame_ns`` keep the spacing of their frames' timestamps, so a
    file that was tracked faster or slower than it plays replays at the video's
    pace; an event without one (a key of a button input, a format-1 line) keeps
    its written offset from the event before it. When frame timestamps go back
    (a source reopened), the written gap bridges the two.

    >>> ev = [{"t_ns": 0, "frame_ns": 0}, {"t_ns": 1_000, "frame_ns": 33_000_000},
    ...       {"t_ns": 1_500}, {"t_ns": 2_000, "frame_ns": 66_000_000}]
    >>> schedule_ns(ev)
    [0, 33000000, 33000500, 66000000]
    >>> schedule_ns(ev, "written")
    [0, 1000, 1500, 2000]
    """
    out: list[int] = []
    last_t: int | None = None
    last_at = 0
    frame_ref: tuple[int, int] | None = None  # (frame_ns, scheduled at) of the last framed event
    for e in events:
        t = e["t_ns"]
        at = 0 if last_t is None else last_at + max(0, t - last_t)
        f = e.get("frame_ns") if timing == "frames" else None
        if f is not None:
            if frame_ref is not None and f >= frame_ref[0]:
                at = frame_ref[1] + (f - frame_ref[0])
            frame_ref = (f, at)
        at = max(at, last_at)
        out.append(at)
        last_t, last_at = t, at
    return out


def replay(
    path: str | Path, sink: PointerSink, *, realtime: bool = True, timing: Timing = "frames"
) -> int:
    """Send a recording's moves and buttons to ``sink``; returns the events sent.

    With ``realtime`` the original pace is kept (``timing``: see
    :func:`schedule_ns`), except that a pause longer than :data:`MAX_PAUSE_S` is cut
    to that (a recording that sat idle, or a clock jump, does not freeze the
    replay). Buttons still down at the end are released (the sink's close does it
    too). The whole recording is checked before the first event.
    """
    events = [e for e in read_events(path) if e["kind"] in ("move", "button")]
    at: list[int] = []
    cut = prev = 0
    for due in schedule_ns(events, timing):
        cut += max(0, due - prev - int(MAX_PAUSE_S * 1e9))
        at.append(due - cut)
        prev = due
    sent = 0
    t0 = time.monotonic_ns()
    for event, due in zip(events, at, strict=True):
        if realtime:
            delay = due - (time.monotonic_ns() - t0)
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
