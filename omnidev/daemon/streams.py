"""The daemon's video streams: source -> camera -> views -> outputs, beside the pointer.

A ``[[stream]]`` section of the configuration (:func:`parse_streams`)::

    [[stream]]
    name = "room"                          # unique; names the stream in status and logs
    source = "v4l2:/dev/video0?width=1920&height=1920&fps=30"
    camera = "/etc/omnidev/room.yml"       # calibration file (any camera kind)
    camera_options = { lookup = "nearest" } # optional: unwarper options
    interpolation = "linear"               # linear, nearest or cubic
    fps = 30.0                             # optional: the outputs' rate (default: the source's)
    queue = 2                              # frames waiting for the remap (1 .. 16)

    [[stream.view]]
    name = "ptz"                           # unique in the daemon: `omnidev ctl view ptz ...`
    view = "perspective:1280x720,fov=70"   # omnidev.viewspec text
    output = ["v4l2:/dev/video10"]         # one or more omnidev.outputs URIs
    max_deg_s = 90.0                       # PTZ: largest angular rate of a move (0: jump)
    follow = "pano"                        # optional: auto-framing from that panorama view
    follow_method = "mog2"                 # mog2 or knn (omnidev.autoframe)

Each running stream (:class:`Stream`) has three threads:

- *capture* opens the source and queues frames; a live source's oldest frame is
  dropped when the queue is full (``dropped_frames``), a recorded one waits. A live
  source that fails (unplugged) is reopened with the daemon's backoff
  (``retry_initial_s`` doubling up to ``retry_max_s``), as the pointer's source is;
  a file that ends ends the stream (its file outputs are committed), a file that is
  corrupt fails it.
- *remap* takes each frame, applies every view's maps and writes the result to the
  view's outputs (opened at the first frame, with the source's size and rate).
  Latency = monotonic time when the last output of the frame returned minus the
  time the source delivered the frame (its capture time for a camera).
- *steer* (only when a view is a perspective one) builds new maps when a view's
  :class:`~omnidev.ptz.ViewController` moves, off the remap thread, and swaps the
  finished :class:`~omnidev.camera.Remapper` in with one assignment. The remap
  thread reads a view's remapper once per frame, so a frame is made with either
  the old or the new maps, never a mix. The steer thread steps the controller once
  per frame time (or per rebuild, when a rebuild takes longer); poses passed
  through are built coarsely (:func:`~omnidev.ptz.coarse_maps`, rays at every
  4th or 8th pixel) when the view found that faster at its start (exact maps
  that take more than half a frame: the non-SVP mirror has no fast map path); the
  pose a move ends at is shown coarse first, then exact. A jump (``max_deg_s`` 0)
  is always built exactly.

A perspective view with ``follow = "NAME"`` is steered by auto-framing
(:class:`~omnidev.autoframe.AutoFramer`): every frame of the stream's panorama view
NAME (it needs an elevation band, ``panorama:WxH,elev=LO:HI``) is fed to the framer
on the remap thread, and its target (pan, tilt) becomes the view's controller target,
moved at ``max_deg_s`` as a ``ctl view`` move would be. While the framer follows an
object its target overrides a ``ctl view`` pan/tilt of that view (the fov stays the
user's); with nothing followed the view stays where it was last sent.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, cast

import numpy as np

from omnidev import registry
from omnidev.autoframe import METHODS as AUTOFRAME_METHODS
from omnidev.autoframe import AutoFrameConfig, AutoFramer
from omnidev.camera import CameraModel, Remapper, build_maps
from omnidev.daemon.queues import put_dropping_oldest
from omnidev.errors import ConfigError, FileSourceError, OmnidevError, PluginError
from omnidev.frame import Frame
from omnidev.inputfile import not_a_file
from omnidev.outputs import GROUP as OUTPUTS
from omnidev.outputs import MAX_FPS, Output, OutputSpec, open_output, split_output_uri
from omnidev.outputs.pixels import to_layout
from omnidev.ptz import Pose, ViewController, coarse_maps
from omnidev.sources import open_source, resolve_uri
from omnidev.views import Panorama, Perspective, View
from omnidev.viewspec import parse_view

log = logging.getLogger("omnidevd")

INTERPOLATIONS = ("linear", "nearest", "cubic")
STREAM_KEYS = {
    "name", "source", "camera", "camera_options", "interpolation", "fps", "queue", "view",
}  # fmt: skip
VIEW_KEYS = {"name", "view", "output", "max_deg_s", "follow", "follow_method"}
MAX_STREAM_QUEUE = 16
DEFAULT_FPS = 30.0
MOVING_MAP_STEPS = (4, 8)
"""Poses a view passes through may be built from rays at every 4th (or, when that
still takes longer than a 30 fps frame, every 8th) pixel."""
FRAME_BUDGET_S = 1 / 30


@dataclass(frozen=True)
class ViewConfig:
    """One view of a stream: its name, parsed view, output URIs and PTZ rate limit."""

    name: str
    spec: str
    view: View
    outputs: tuple[str, ...]
    max_deg_s: float = 90.0
    follow: str | None = None
    follow_method: str = "mog2"

    @property
    def steerable(self) -> bool:
        return isinstance(self.view, Perspective)


@dataclass(frozen=True)
class StreamConfig:
    """One ``[[stream]]`` section, validated (paths resolved against the config's folder)."""

    name: str
    source: str
    camera: Path
    views: tuple[ViewConfig, ...]
    camera_options: dict[str, str] = field(default_factory=dict)
    interpolation: str = "linear"
    fps: float | None = None
    queue: int = 2


def parse_streams(doc: Any, path: Path) -> tuple[StreamConfig, ...]:
    """Validate the ``stream`` array of tables; a :class:`ConfigError` names the key."""

    def fail(key: str, msg: str) -> ConfigError:
        return ConfigError(f"{path}: {key}: {msg}")

    if doc is None:
        return ()
    if not isinstance(doc, list) or not all(isinstance(s, dict) for s in doc):
        raise fail("stream", "must be an array of tables ([[stream]])")
    streams: list[StreamConfig] = []
    stream_names: set[str] = set()
    view_names: set[str] = set()
    outputs_seen: dict[tuple[str, str], str] = {}
    for i, table in enumerate(doc):
        where = f"stream[{i}]"
        for key in table:
            if key not in STREAM_KEYS:
                known = ", ".join(sorted(STREAM_KEYS))
                raise fail(f"{where}.{key}", f"unknown key (keys of [[stream]]: {known})")

        def get(
            key: str,
            kind: type | tuple[type, ...],
            default: Any = None,
            table: dict[str, Any] = table,
            where: str = where,
        ) -> Any:
            value = table.get(key, default)
            if value is None:
                raise fail(f"{where}.{key}", "missing (required)")
            kinds = kind if isinstance(kind, tuple) else (kind,)
            if (isinstance(value, bool) and bool not in kinds) or not isinstance(value, kind):
                raise fail(f"{where}.{key}", f"must be {_kind(kinds)}, got {value!r}")
            if isinstance(value, str) and (not value.strip() or "\0" in value):
                raise fail(f"{where}.{key}", "is empty or holds a NUL character")
            return value

        name = get("name", str, f"stream{i}")
        if name in stream_names:
            raise fail(f"{where}.name", f"stream {name!r} given twice")
        stream_names.add(name)
        where = f"stream {name!r}"
        source = resolve_uri(get("source", str, where=where), path.parent)
        camera = Path(get("camera", str, where=where))
        if not camera.is_absolute():
            camera = path.parent / camera
        why = not_a_file(camera, "camera file")
        if why is not None:
            raise fail(f"{where}.camera", f"{camera}: {why}")
        options = get("camera_options", dict, {}, where=where)
        camera_options = {str(k): str(v) for k, v in options.items()}
        interpolation = get("interpolation", str, "linear", where=where)
        if interpolation not in INTERPOLATIONS:
            raise fail(
                f"{where}.interpolation",
                f"must be one of {', '.join(INTERPOLATIONS)}, got {interpolation!r}",
            )
        fps_value = table.get("fps")
        fps: float | None = None
        if fps_value is not None:
            fps = float(get("fps", (int, float), where=where))
            if not 0 < fps <= MAX_FPS:
                raise fail(f"{where}.fps", f"must be in (0, {MAX_FPS:g}], got {fps_value!r}")
        depth = get("queue", int, 2, where=where)
        if not 1 <= depth <= MAX_STREAM_QUEUE:
            raise fail(f"{where}.queue", f"must be 1 .. {MAX_STREAM_QUEUE} frames, got {depth}")
        raw_views = table.get("view")
        if not isinstance(raw_views, list) or not raw_views:
            raise fail(f"{where}.view", "give at least one [[stream.view]] table")
        views: list[ViewConfig] = []
        for j, vt in enumerate(raw_views):
            vwhere = f"{where}.view[{j}]"
            if not isinstance(vt, dict):
                raise fail(vwhere, "must be a table ([[stream.view]])")
            for key in vt:
                if key not in VIEW_KEYS:
                    known = ", ".join(sorted(VIEW_KEYS))
                    raise fail(f"{vwhere}.{key}", f"unknown key (keys of [[stream.view]]: {known})")
            vname = vt.get("name", f"{name}.{j}")
            if not isinstance(vname, str) or not vname.strip() or any(c.isspace() for c in vname):
                raise fail(f"{vwhere}.name", f"must be a name without spaces, got {vname!r}")
            if vname in view_names:
                raise fail(f"{vwhere}.name", f"view {vname!r} given twice (names are daemon-wide)")
            view_names.add(vname)
            vwhere = f"{where}.view {vname!r}"
            spec = vt.get("view")
            if not isinstance(spec, str):
                raise fail(f"{vwhere}.view", "missing: a view such as 'perspective:640x480,fov=70'")
            try:
                view = parse_view(spec)
            except OmnidevError as exc:
                raise fail(f"{vwhere}.view", str(exc)) from None
            outs = vt.get("output")
            if isinstance(outs, str):
                outs = [outs]
            if not isinstance(outs, list) or not outs or not all(isinstance(o, str) for o in outs):
                raise fail(f"{vwhere}.output", "give an output URI or a list of them")
            resolved = []
            for o in outs:
                scheme, rest, _ = split_output_uri(o)
                try:
                    registry.get(OUTPUTS, scheme)
                except PluginError as exc:
                    raise fail(f"{vwhere}.output", f"{o}: {exc}") from None
                if scheme == "file" or (scheme in ("y4m", "raw") and rest not in ("", "-")):
                    p = Path(rest)
                    if not p.is_absolute():
                        o = o.replace(rest, str(path.parent / p), 1)
                        rest = str(path.parent / p)
                key = (scheme if scheme not in ("y4m", "raw") else "pipe", rest)
                if key in outputs_seen:
                    raise fail(f"{vwhere}.output", f"{o} is also written by {outputs_seen[key]}")
                outputs_seen[key] = vname
                resolved.append(o)
            rate = vt.get("max_deg_s", 90.0)
            if isinstance(rate, bool) or not isinstance(rate, int | float):
                raise fail(f"{vwhere}.max_deg_s", f"must be a number, got {rate!r}")
            if not (0 <= rate <= 1e6 and math.isfinite(rate)):
                raise fail(f"{vwhere}.max_deg_s", f"must be 0 (jump) .. 1e6 deg/s, got {rate}")
            if "max_deg_s" in vt and not isinstance(view, Perspective):
                raise fail(f"{vwhere}.max_deg_s", "only a perspective view is steerable")
            follow = vt.get("follow")
            method = vt.get("follow_method", "mog2")
            if follow is not None:
                if not isinstance(view, Perspective):
                    raise fail(f"{vwhere}.follow", "only a perspective view is steered")
                if not isinstance(follow, str) or not follow.strip():
                    raise fail(f"{vwhere}.follow", f"must be a view name, got {follow!r}")
            if not isinstance(method, str) or method not in AUTOFRAME_METHODS:
                raise fail(
                    f"{vwhere}.follow_method",
                    f"must be one of {', '.join(AUTOFRAME_METHODS)}, got {method!r}",
                )
            if "follow_method" in vt and follow is None:
                raise fail(f"{vwhere}.follow_method", "given without follow")
            views.append(
                ViewConfig(vname, spec, view, tuple(resolved), float(rate), follow, method)
            )
        by_name = {v.name: v for v in views}
        for v in views:
            if v.follow is None:
                continue
            followed = by_name.get(v.follow)
            vwhere = f"{where}.view {v.name!r}.follow"
            if followed is None:
                known = ", ".join(sorted(by_name))
                raise fail(vwhere, f"no view {v.follow!r} in this stream (views: {known})")
            if not isinstance(followed.view, Panorama) or followed.view.elevation_deg is None:
                raise fail(
                    vwhere,
                    f"view {v.follow!r} must be a panorama with an elevation band "
                    "(panorama:WxH,elev=LO:HI)",
                )
        streams.append(
            StreamConfig(
                name, source, camera, tuple(views), camera_options, interpolation, fps, depth
            )
        )
    return tuple(streams)


def _kind(kinds: tuple[type, ...]) -> str:
    names = {str: "a string", int: "an integer", float: "a number", dict: "a table"}
    if set(kinds) == {int, float}:
        return "a number"
    return " or ".join(names.get(k, k.__name__) for k in kinds)


def perspective_at(view: Perspective, pose: Pose) -> Perspective:
    """``view`` turned to ``pose`` (size and roll kept)."""
    return replace(view, pan_deg=pose.pan, tilt_deg=pose.tilt, fov_deg=pose.fov)


class LiveView:
    """A view of a running stream: its current remapper, and for a perspective view its
    :class:`~omnidev.ptz.ViewController` and the pose its current maps were built for."""

    def __init__(self, config: ViewConfig, camera: CameraModel, interpolation: str) -> None:
        self.config = config
        self.camera = camera
        self.interpolation = interpolation
        t0 = time.perf_counter()
        self.remapper = Remapper(build_maps(camera, config.view), interpolation=interpolation)  # type: ignore[arg-type]
        exact_s = time.perf_counter() - t0
        self.moving_step = 1  # poses passed through: coarse maps (step > 1) when faster
        self.controller: ViewController | None = None
        self.built: Pose | None = None
        self.rebuild_ms: deque[float] = deque(maxlen=200)
        self.built_exact = True
        self.rebuilds = 0
        if isinstance(config.view, Perspective):
            v = config.view
            self.built = Pose(v.pan_deg, v.tilt_deg, v.fov_deg)
            self.controller = ViewController(self.built, config.max_deg_s)
            self.built = self.controller.pose
            best = exact_s
            for step in MOVING_MAP_STEPS:
                if best <= FRAME_BUDGET_S / 2:
                    break
                t0 = time.perf_counter()
                Remapper(coarse_maps(camera, config.view, step))
                took = time.perf_counter() - t0
                if took < 0.8 * best:
                    self.moving_step, best = step, took
        self.framer: AutoFramer | None = None
        self.follow_targets = 0
        self.outputs: list[Output] = []
        self.written = 0
        self.history: deque[tuple[int, Pose | None]] = deque(maxlen=4096)

    def rebuild(self, pose: Pose, exact: bool = True) -> None:
        """Build maps for ``pose`` and swap them in (one assignment: atomic for readers).

        ``exact`` False (a pose passed through while moving): :func:`~omnidev.ptz.coarse_maps`
        at every ``moving_step``-th pixel, which the view chose when it started: the
        fastest of exact maps and :data:`MOVING_MAP_STEPS` (tried while the best so far
        takes more than half a 30 fps frame)."""
        assert isinstance(self.config.view, Perspective)
        t0 = time.perf_counter()
        view = perspective_at(self.config.view, pose)
        maps = (
            build_maps(self.camera, view)
            if exact or self.moving_step == 1
            else coarse_maps(self.camera, view, self.moving_step)
        )
        remapper = Remapper(maps, interpolation=self.interpolation)  # type: ignore[arg-type]
        self.rebuild_ms.append((time.perf_counter() - t0) * 1000)
        self.remapper, self.built = remapper, pose  # the frame thread reads remapper once
        self.built_exact = exact
        self.rebuilds += 1

    def status(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "name": self.config.name,
            "view": self.config.spec,
            "outputs": [o.name for o in self.outputs] or list(self.config.outputs),
            "written": self.written,
        }
        if self.controller is not None:
            b, t = self.built, self.controller.target
            assert b is not None
            out["pose"] = {"pan": round(b.pan, 4), "tilt": round(b.tilt, 4), "fov": round(b.fov, 4)}
            out["target"] = {"pan": t.pan, "tilt": t.tilt, "fov": t.fov}
            out["max_deg_s"] = self.controller.max_deg_s
            out["rebuilds"] = self.rebuilds
            out["moving_map_step"] = self.moving_step
            ms = list(self.rebuild_ms)
            out["rebuild_ms_p50"] = round(float(np.percentile(ms, 50)), 3) if ms else None
            out["rebuild_ms_max"] = round(max(ms), 3) if ms else None
        if self.config.follow is not None:
            out["follow"] = self.config.follow
            out["follow_method"] = self.config.follow_method
            out["follow_targets"] = self.follow_targets
        return out


class Stream:
    """One running ``[[stream]]``; see the module docstring."""

    def __init__(
        self, config: StreamConfig, retry_initial_s: float = 0.5, retry_max_s: float = 10.0
    ) -> None:
        from omnidev.calibfile import load_camera

        self.config = config
        self.retry_initial_s = retry_initial_s
        self.retry_max_s = retry_max_s
        self.camera = load_camera(config.camera, config.camera_options)
        try:
            self.views = [LiveView(v, self.camera, config.interpolation) for v in config.views]
        except ValueError as exc:
            raise ConfigError(f"stream {config.name!r}: {config.camera}: {exc}") from None
        by_name = {v.config.name: v for v in self.views}
        for v in self.views:
            if v.config.follow is not None:
                pano = by_name[v.config.follow].config.view
                assert isinstance(pano, Panorama)
                v.framer = AutoFramer(AutoFrameConfig(pano, method=v.config.follow_method))
        self.state = "starting"
        self.started = time.monotonic()
        self.frames = 0
        self.processed = 0
        self.written = 0
        self.dropped = 0
        self.bad_frames = 0
        self.output_errors = 0
        self.camera_retries = 0
        self.source_live: bool | None = None
        self.source_fps: float | None = None
        self.error: str | None = None
        self.source_failed = False
        self.output_failed = False  # an output could not be opened or the remap failed
        self.ended = threading.Event()
        self.finished = threading.Event()
        self.heartbeat = time.monotonic()
        self._latency_ns: deque[int] = deque(maxlen=2000)
        self._times_ns: deque[int] = deque(maxlen=120)
        self._queue: queue.Queue[Frame | None] = queue.Queue(maxsize=config.queue)
        self._stop = threading.Event()
        self._paused = threading.Event()
        self._steer = threading.Event()
        self._output_failing = False
        self._capture_done = False  # the capture thread ended with its file
        self._threads = [
            threading.Thread(target=self._capture_loop, name=f"capture:{config.name}", daemon=True),
            threading.Thread(target=self._remap_loop, name=f"remap:{config.name}", daemon=True),
        ]
        if any(v.controller is not None for v in self.views):
            self._threads.append(
                threading.Thread(target=self._steer_loop, name=f"steer:{config.name}", daemon=True)
            )

    # -- control ---------------------------------------------------------------
    def start(self) -> None:
        for t in self._threads:
            t.start()

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        self._steer.set()
        for t in self._threads:
            if t.is_alive():
                t.join(timeout)
        self._close_outputs()
        if self.state not in ("ended", "failed"):
            self.state = "stopped"

    def pause(self) -> None:
        self._paused.set()

    def resume(self) -> None:
        self._paused.clear()

    @property
    def alive(self) -> bool:
        """Every thread runs (the capture thread may have ended with its file), or the
        stream has finished."""
        if self.finished.is_set():
            return True
        capture, *others = self._threads
        return (capture.is_alive() or self._capture_done) and all(t.is_alive() for t in others)

    def healthy(self, max_silence_s: float = 5.0) -> bool:
        return self.finished.is_set() or (
            self.alive and time.monotonic() - self.heartbeat < max_silence_s
        )

    def view(self, name: str) -> LiveView | None:
        return next((v for v in self.views if v.config.name == name), None)

    def steer(self, name: str, absolute: dict[str, float], relative: dict[str, float]) -> LiveView:
        """Set a view's target; the steer thread starts moving at once."""
        v = self.view(name)
        if v is None or v.controller is None:
            raise OmnidevError(f"view {name!r} is not a perspective view (only those steer)")
        c = v.controller
        c.set_target(absolute.get("pan"), absolute.get("tilt"), absolute.get("fov"))
        if relative:
            c.move(relative.get("pan", 0.0), relative.get("tilt", 0.0), relative.get("fov", 0.0))
        self._steer.set()
        return v

    def status(self) -> dict[str, Any]:
        lat = np.array(self._latency_ns, np.float64) / 1e6
        times = list(self._times_ns)
        fps = (len(times) - 1) / ((times[-1] - times[0]) / 1e9) if len(times) > 1 else 0.0
        state = self.state
        if self._paused.is_set() and state == "running":
            state = "paused"
        return {
            "name": self.config.name,
            "state": state,
            "source": self.config.source,
            "source_kind": None
            if self.source_live is None
            else ("live" if self.source_live else "recorded"),
            "camera": str(self.config.camera),
            "fps": round(fps, 2),
            "latency_p50_ms": round(float(np.percentile(lat, 50)), 3) if lat.size else None,
            "latency_p99_ms": round(float(np.percentile(lat, 99)), 3) if lat.size else None,
            "frames": self.frames,
            "written": self.written,
            "dropped_frames": self.dropped,
            "bad_frames": self.bad_frames,
            "output_errors": self.output_errors,
            "camera_retries": self.camera_retries,
            "views": [v.status() for v in self.views],
            "error": self.error,
        }

    # -- threads ---------------------------------------------------------------
    def _put(self, frame: Frame, live: bool) -> bool:
        if not live:
            while not self._stop.is_set():
                try:
                    self._queue.put(frame, timeout=0.05)
                    return True
                except queue.Full:
                    if not self._threads[1].is_alive():
                        return False
            return False
        self.dropped += put_dropping_oldest(self._queue, frame)
        return True

    def _capture_loop(self) -> None:
        delay = self.retry_initial_s
        uri = self.config.source
        while not self._stop.is_set():
            try:
                source = open_source(uri)
            except FileSourceError as exc:
                self._fail(str(exc))
                return
            except OmnidevError as exc:
                self._wait_for_camera(exc, delay)
                delay = min(delay * 2, self.retry_max_s)
                continue
            live = bool(getattr(source, "live", True))
            try:
                with source:
                    self.source_live = live
                    fps = getattr(source, "fps", None)
                    self.source_fps = float(fps) if fps and 0 < fps <= MAX_FPS else None
                    log.info("stream %s: source %s open", self.config.name, uri)
                    self.state = "running"
                    delay = self.retry_initial_s
                    for frame in source:
                        if not self._put(frame, live):
                            return
                        self.frames += 1
                        if self._stop.is_set():
                            return
                    if not live:
                        self._put_end()
                        self._capture_done = True
                        return
            except Exception as exc:
                if isinstance(exc, FileSourceError) or not live:
                    self._put_end()
                    self._capture_done = True
                    self._fail(str(exc) if isinstance(exc, OmnidevError) else f"{uri}: {exc!r}")
                    return
                if not isinstance(exc, OmnidevError):
                    log.exception("stream %s: source %s failed", self.config.name, uri)
                self._wait_for_camera(exc, delay)
                delay = min(delay * 2, self.retry_max_s)

    def _put_end(self) -> None:
        while not self._stop.is_set():
            try:
                self._queue.put(None, timeout=0.05)
                return
            except queue.Full:
                if not self._threads[1].is_alive():
                    return

    def _fail(self, msg: str) -> None:
        self.error = msg
        self.source_failed = True
        self.state = "failed"
        log.error("stream %s: %s; not retrying (a file is not a camera)", self.config.name, msg)
        self._stop.set()
        self._steer.set()
        self.finished.set()

    def _wait_for_camera(self, exc: BaseException, delay: float) -> None:
        if self._stop.is_set():
            return
        self.state = "waiting for camera"
        self.camera_retries += 1
        log.warning("stream %s: %s; retrying in %.1f s", self.config.name, exc, delay)
        self._stop.wait(delay)

    def _open_outputs(self) -> None:
        fps = self.config.fps or self.source_fps or DEFAULT_FPS
        for v in self.views:
            h, w = v.remapper.maps.shape
            spec = OutputSpec((w, h), fps, ("bgr",), True, bool(self.source_live), 1)
            for uri in v.config.outputs:
                v.outputs.append(open_output(uri, spec))

    def _close_outputs(self) -> None:
        for v in self.views:
            for out in v.outputs:
                try:
                    out.close()
                except Exception as exc:
                    log.error("stream %s: closing %s: %s", self.config.name, out.name, exc)
            v.outputs = []

    def _remap_loop(self) -> None:
        opened = False
        size = self.camera.image_size
        try:
            while not self._stop.is_set():
                self.heartbeat = time.monotonic()
                try:
                    frame = self._queue.get(timeout=0.05)
                except queue.Empty:
                    continue
                if frame is None:  # a recorded source ended
                    self._close_outputs()
                    if self.state != "failed":
                        self.state = "ended"
                        log.info("stream %s: source ended after %d frames", self.config.name,
                                 self.frames)  # fmt: skip
                        self.ended.set()
                    self.finished.set()
                    return
                self.processed += 1
                if self._paused.is_set():
                    continue
                h, w = frame.image.shape[:2]
                if (w, h) != size:
                    self.bad_frames += 1
                    if self.bad_frames == 1:
                        log.error(
                            "stream %s: %s frame %d is %dx%d, the calibration is for %dx%d; "
                            "skipping such frames",
                            self.config.name, self.config.source, frame.index, w, h, *size,
                        )  # fmt: skip
                    continue
                if not opened:
                    self._open_outputs()
                    opened = True
                self._write(frame)
        except Exception as exc:
            self.error = f"stream {self.config.name}: {exc}"
            log.error("%s", self.error)
            self.state = "failed"
            self.output_failed = True
            self._stop.set()
            self.finished.set()
            for v in self.views:
                for out in v.outputs:
                    out.abort()
                v.outputs = []

    def _write(self, frame: Frame) -> None:
        image = frame.image
        if image.ndim == 2:
            image = np.stack([image] * 3, axis=-1)
        images: dict[str, Any] = {}
        for v in self.views:
            remapper, pose = v.remapper, v.built  # one read: old or new maps, never a mix
            out_image = remapper(cast(Any, image))
            images[v.config.name] = out_image
            v.history.append((frame.index, pose))
            for out in v.outputs:
                img = out_image if out.layout == "bgr" else to_layout(out_image, "bgr", out.layout)
                try:
                    out.write(Frame(img, frame.timestamp_ns, frame.index, frame.monotonic_ns))
                except OmnidevError as exc:
                    self.output_errors += 1
                    if not self._output_failing:
                        log.error("stream %s: %s (going on)", self.config.name, exc)
                    self._output_failing = True
            v.written += 1
        for v in self.views:
            if v.framer is not None and v.controller is not None and v.config.follow:
                target = v.framer.update(images[v.config.follow], frame.timestamp_ns / 1e9)
                if target is not None:
                    v.controller.set_target(target.pan_deg, target.tilt_deg, None)
                    v.follow_targets += 1
                    self._steer.set()
        done = time.monotonic_ns()
        self.written += 1
        self._latency_ns.append(done - frame.monotonic_ns)
        self._times_ns.append(done)

    def _steer_loop(self) -> None:
        last = time.monotonic()
        while not self._stop.is_set():
            moving = [v for v in self.views if v.controller and not v.controller.settled]
            if not moving:
                self._steer.wait(0.5)
                self._steer.clear()
                last = time.monotonic()
                continue
            period = 1.0 / (self.config.fps or self.source_fps or DEFAULT_FPS)
            now = time.monotonic()
            dt = max(now - last, period)  # the first step of a move: one frame's worth
            last = now
            for v in moving:
                assert v.controller is not None
                pose = v.controller.step(dt)
                try:
                    settled = v.controller.settled
                    jump = v.controller.max_deg_s == 0
                    if not settled or (v.moving_step > 1 and not jump):
                        v.rebuild(pose, exact=False)  # the last pose at once, refined below
                    if settled:
                        v.rebuild(pose, exact=True)
                except Exception as exc:  # a pose the camera cannot show: stay where it is
                    log.error("stream %s: view %s: %s", self.config.name, v.config.name, exc)
                    v.controller.set_target(v.built.pan, v.built.tilt, v.built.fov)  # type: ignore[union-attr]
                    v.controller.step(1e9)
            self._steer.wait(max(0.0, period - (time.monotonic() - now)))
            self._steer.clear()
