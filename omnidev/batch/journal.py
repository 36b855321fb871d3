"""The job manifest: what a batch job has finished, so that a rerun does only the rest.

``OUT/.omnidev-batch/journal.jsonl`` holds one JSON object a line, appended
as work finishes (flushed at once, synced to disk at most once a second and
at the end):

- ``index``, when a video is indexed: ``unit``, ``input``, ``index`` (frames,
  size, fps, ranges);
- ``range``, when a range's segments are in place: ``unit``, ``range``,
  ``frames``, ``segments`` (path, bytes);
- ``done``, when an input's outputs are in place: ``unit``, ``input``,
  ``outputs``, ``frames``;
- ``failed``, when an input failed (informative; a rerun tries it again):
  ``unit``, ``input``, ``error``.

A *unit* is one input with one camera, set of views and output settings; its
key (:func:`unit_key`) is a hash of the input file's path, size and
modification time, the calibration file's bytes and the settings, so a
changed input, calibration or setting is new work and never mixes with old
records. A line cut short by a crash is ignored. A ``range`` counts as done
only while its segment files exist with the recorded sizes, a ``done`` only
while its outputs exist. One job at a time may use a folder (a lock file).
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from omnidev.errors import OmnidevError

STATE_DIR = ".omnidev-batch"


def file_hash(path: Path) -> str:
    """SHA-256 of a file's bytes (a calibration file: small)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def unit_key(input_path: Path, camera_hash: str, settings: dict[str, Any]) -> str:
    """The key of one unit of work (see the module docstring); 20 hex digits."""
    st = input_path.stat()
    ident = {
        "input": str(input_path),
        "size": st.st_size,
        "mtime_ns": st.st_mtime_ns,
        "camera": camera_hash,
        "settings": settings,
    }
    text = json.dumps(ident, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


@dataclass
class JournalState:
    """The records of a journal, by unit key."""

    index: dict[str, dict[str, Any]] = field(default_factory=dict)
    ranges: dict[str, dict[int, dict[str, Any]]] = field(default_factory=dict)
    done: dict[str, dict[str, Any]] = field(default_factory=dict)

    def range_done(self, unit: str, number: int) -> dict[str, Any] | None:
        """The record of a finished range whose segments are still in place, else None."""
        rec = self.ranges.get(unit, {}).get(number)
        if rec is None:
            return None
        for seg in rec["segments"]:
            p = Path(seg["path"])
            if not p.is_file() or p.stat().st_size != seg["bytes"]:
                return None
        return rec

    def unit_done(self, unit: str) -> dict[str, Any] | None:
        """The ``done`` record of a unit whose outputs all exist, else None."""
        rec = self.done.get(unit)
        if rec is None:
            return None
        if all(Path(p).is_file() for p in rec["outputs"]):
            return rec
        return None


class Journal:
    """The job manifest of one output folder (see the module docstring).

    Open it with ``with Journal(out_dir) as j:``; :meth:`load` reads what an
    earlier run recorded, :meth:`record` appends.
    """

    def __init__(self, out_dir: Path, *, sync_interval_s: float = 1.0) -> None:
        self.dir = Path(out_dir) / STATE_DIR
        self.path = self.dir / "journal.jsonl"
        self.segments_dir = self.dir / "segments"
        self._sync_interval = sync_interval_s
        self._file: IO[str] | None = None
        self._lock: IO[str] | None = None
        self._last_sync = 0.0

    def __enter__(self) -> Journal:
        self.dir.mkdir(parents=True, exist_ok=True)
        self._lock = open(self.dir / "lock", "w")
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self._lock.close()
            self._lock = None
            raise OmnidevError(
                f"{self.dir.parent}: another omnidev batch job is using this folder"
            ) from None
        self._file = open(self.path, "a", encoding="utf-8")
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        if self._file is not None:
            self._file.flush()
            with contextlib.suppress(OSError):
                os.fsync(self._file.fileno())
            self._file.close()
            self._file = None
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def load(self) -> JournalState:
        """Every complete record written so far (a torn last line is skipped)."""
        state = JournalState()
        if not self.path.is_file():
            return state
        with open(self.path, encoding="utf-8") as f:
            for line in f:
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if not isinstance(rec, dict) or "unit" not in rec:
                    continue
                kind, unit = rec.get("kind"), str(rec["unit"])
                if kind == "index":
                    state.index[unit] = rec
                elif kind == "range":
                    state.ranges.setdefault(unit, {})[int(rec["range"])] = rec
                elif kind == "done":
                    state.done[unit] = rec
        return state

    def record(self, rec: dict[str, Any]) -> None:
        """Append one record (flushed now; synced to disk at most every ``sync_interval_s``)."""
        if self._file is None:
            raise RuntimeError("journal is not open")
        self._file.write(json.dumps(rec, sort_keys=True) + "\n")
        self._file.flush()
        now = time.monotonic()
        if now - self._last_sync >= self._sync_interval:
            with contextlib.suppress(OSError):
                os.fsync(self._file.fileno())
            self._last_sync = now

    def unit_segments(self, unit: str) -> Path:
        """The folder holding a unit's segment files."""
        return self.segments_dir / unit
