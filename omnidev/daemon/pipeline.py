"""The pointer pipeline: source -> tracker -> One Euro filter -> sink, on its own threads.

Two threads:

- *capture* opens the source and puts frames into a bounded queue
  (``[daemon] queue`` frames, at most :data:`~omnidev.daemon.config.MAX_QUEUE`).
  What happens when the queue is full depends on the source
  (:attr:`omnidev.sources.Source.live`):

  - a *live* source (a camera, a file paced with ``rate=``): the oldest frame is
    dropped and counted (``dropped_frames``), so a slow tracker costs frames,
    never latency. When the camera fails (unplugged) the capture thread logs,
    tells the worker to release every button, and reopens the source with
    exponential backoff until it comes back.
  - a *recorded* source (a video file, an image set): the reader waits for the
    tracker, so no frame is ever dropped; pausing pauses the reading. When the
    file ends, the run ends (``state`` "ended"); a missing, truncated or corrupt
    file (:class:`~omnidev.errors.FileSourceError`) ends it with that error
    (``state`` "failed") once the frames before it are processed; it is never
    reopened as a camera would be.
- *worker* takes frames, runs the tracker, filters the sample and hands it to
  the sink. Only this thread touches the sink; it closes the sink (releasing
  buttons) when it ends, whatever the reason.

The filter and the dwell click run on the frames' own timestamps
(:attr:`Frame.timestamp_ns <omnidev.frame.Frame>`: capture time of a live
frame, presentation time of a file's frame), so a file behaves as the same video
would live. Latency of a frame = monotonic time when the sink call returned (the
event is with the OS) minus the monotonic time the source delivered the frame
(:attr:`Frame.monotonic_ns <omnidev.frame.Frame>`): for a camera that is its
capture time; for a file it is the moment the frame was decoded, so a file's
latency is omnidev's own (queue, tracker, filter, sink), without a camera's.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from omnidev.buttons import ButtonInput, ButtonInputError, DwellClicker, open_buttons
from omnidev.daemon.config import DaemonConfig
from omnidev.daemon.queues import put_dropping_oldest
from omnidev.errors import FileSourceError, OmnidevError
from omnidev.filters import OneEuroFilter
from omnidev.frame import Frame, PointerSample
from omnidev.sinks import PointerSink, open_sink
from omnidev.sources import open_source
from omnidev.tracking import Tracker, open_tracker

log = logging.getLogger("omnidevd")


@dataclass
class _Stats:
    frames: int = 0
    tracked: int = 0
    dropped_frames: int = 0
    tracker_errors: int = 0
    sink_errors: int = 0
    camera_retries: int = 0
    processed: int = 0  # frames the worker has taken from the queue


class Pipeline:
    """Runs one configuration; :meth:`reload` swaps in another without a restart.

    Args:
        config: the validated configuration.
        on_sample: optional callback ``(sample, t_done_ns)`` after each sink
            call, from the worker thread (tests and benchmarks use it).
        log_fatal: log the error that stops the pipeline (:attr:`fatal`); a
            caller that reports it itself (the foreground commands) passes False.
    """

    def __init__(
        self, config: DaemonConfig, on_sample: Any = None, *, log_fatal: bool = True
    ) -> None:
        self.config = config
        self.on_sample = on_sample
        self.log_fatal = log_fatal
        self.ended = threading.Event()  # set when a recorded source ended and all is processed
        self.finished = threading.Event()  # set when the run ended by itself (ended or fatal)
        self.source_failed = False  # a file source failed: final, restarting cannot help
        self.source_live: bool | None = None  # the open source's kind (None: none opened yet)
        self.state = "starting"
        self.started = time.monotonic()
        self._stats = _Stats()
        self._latency_ns: deque[int] = deque(maxlen=2000)
        self._times_ns: deque[int] = deque(maxlen=120)
        self._queue: queue.Queue[Frame] = queue.Queue(maxsize=config.queue)
        self._lost = threading.Event()  # release buttons, reset, take pending parts
        self._stop = threading.Event()
        self._restart_source = threading.Event()
        self._paused = threading.Event()
        self._lock = threading.Lock()
        self.heartbeat = time.monotonic()
        self._sink_failing = False
        self._size: tuple[int, int] | None = None  # frame size of the open source
        self.fatal: str | None = None  # why the pipeline stopped by itself, if it did
        self.tracker: Tracker = open_tracker(
            config.tracker, config.tracker_options, config.calibration
        )
        self.filter = self._make_filter(config)
        self.buttons_in: ButtonInput | None = (
            open_buttons(config.buttons.input) if config.buttons.input else None
        )
        try:
            self.sink: PointerSink = open_sink(config.sink, config.sink_options, config.screen)
        except BaseException:
            if self.buttons_in is not None:
                self.buttons_in.close()
            raise
        self.dwell = self._make_dwell(config)
        self._held: set[str] = set()  # buttons held down on the button input
        self._dwell_clicks = 0
        self._pending: tuple[Tracker, OneEuroFilter | None, PointerSink | None] | None = None
        # a new button input from reload(): (the input or None,) when one is pending
        self._pending_buttons: tuple[ButtonInput | None] | None = None
        self._capture = threading.Thread(target=self._capture_loop, name="capture", daemon=True)
        self._worker = threading.Thread(target=self._work_loop, name="worker", daemon=True)

    # -- control ---------------------------------------------------------------
    def start(self) -> None:
        self._capture.start()
        self._worker.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop both threads; the worker releases buttons and closes the sink."""
        self._stop.set()
        for t in (self._capture, self._worker):
            if t.is_alive():
                t.join(timeout)
        if not self.sink.closed:  # the worker never ran or is stuck: close here
            self.sink.close()
        self.state = "stopped"

    def pause(self) -> None:
        """Keep capturing but stop moving the pointer; buttons are released."""
        self._paused.set()
        self._lost.set()

    def resume(self) -> None:
        self._paused.clear()

    def reload(self, config: DaemonConfig) -> None:
        """Apply a new configuration: new tracker and filter; new sink or source if changed.

        Opening the new tracker or sink may fail; then nothing changes and the
        error is raised.
        """
        tracker = open_tracker(config.tracker, config.tracker_options, config.calibration)
        buttons: tuple[ButtonInput | None] | None = None
        if config.buttons.input != self.config.buttons.input:
            buttons = (open_buttons(config.buttons.input) if config.buttons.input else None,)
        sink = None
        if (config.sink, config.sink_options, config.screen) != (
            self.config.sink,
            self.config.sink_options,
            self.config.screen,
        ):
            sink = open_sink(config.sink, config.sink_options, config.screen)
        source_changed = config.source != self.config.source
        with self._lock:
            if self._pending is not None and self._pending[2] is not None:
                self._pending[2].close()  # an earlier reload's sink, never used
            self._pending = (tracker, self._make_filter(config), sink)
            if buttons is not None:
                if self._pending_buttons is not None and self._pending_buttons[0] is not None:
                    self._pending_buttons[0].close()  # an earlier reload's, never used
                self._pending_buttons = buttons
            self.dwell = self._make_dwell(config)
            self.config = config
        if source_changed:
            self._restart_source.set()
        self._lost.set()  # the worker picks up the pending parts at once
        log.info("configuration reloaded from %s", config.path)

    @property
    def alive(self) -> bool:
        return self._worker.is_alive() and self._capture.is_alive()

    def healthy(self, max_silence_s: float = 5.0) -> bool:
        """Both threads run and the worker has looked at its queue recently."""
        return self.alive and time.monotonic() - self.heartbeat < max_silence_s

    def status(self) -> dict[str, Any]:
        """Figures for the control socket (latencies in ms over the last 2000 frames)."""
        lat = np.array(self._latency_ns, np.float64) / 1e6
        times = list(self._times_ns)
        fps = (len(times) - 1) / ((times[-1] - times[0]) / 1e9) if len(times) > 1 else 0.0
        s = self._stats
        return {
            "state": "paused" if self._paused.is_set() and self.state == "running" else self.state,
            "source": self.config.source,
            "sink": self.sink.name,
            "tracker": self.config.tracker,
            "fps": round(fps, 2),
            "latency_p50_ms": round(float(np.percentile(lat, 50)), 3) if lat.size else None,
            "latency_p99_ms": round(float(np.percentile(lat, 99)), 3) if lat.size else None,
            "frames": s.frames,
            "tracked": s.tracked,
            "dropped_frames": s.dropped_frames,
            "source_kind": None
            if self.source_live is None
            else ("live" if self.source_live else "recorded"),
            "tracker_errors": s.tracker_errors,
            "sink_errors": s.sink_errors,
            "events": self.sink.events,
            "camera_retries": s.camera_retries,
            "uptime_s": round(time.monotonic() - self.started, 1),
            "buttons_input": self.config.buttons.input or None,
            "buttons_held": sorted(self._held),
            "dwell_clicks": self._dwell_clicks,
            "error": self.fatal,
        }

    def latencies_ns(self) -> list[int]:
        return list(self._latency_ns)

    def summary(self) -> str:
        """One line for the end of a run: frames, drops and why, positions, latency."""
        st = self.status()
        drops = f"{st['dropped_frames']} dropped"
        if st["source_kind"] == "recorded":
            drops += " (a file waits for the tracker)"
        elif st["source_kind"] == "live":
            drops += " (live source: the oldest frame when behind)"
        return (
            f"{st['frames']} frames, {drops}, {st['tracked']} cursor positions, "
            f"latency p50 {st['latency_p50_ms']} ms"
        )

    # -- threads ---------------------------------------------------------------
    def _put(self, frame: Frame, live: bool) -> bool:
        """Queue a frame. Live: when the queue is full, drop the oldest to make room.
        Recorded: wait for room. False when the wait ended by a stop or a source change."""
        if not live:
            while not (self._stop.is_set() or self._restart_source.is_set()):
                if not self._worker.is_alive() and self._worker.ident is not None:
                    return False
                try:
                    self._queue.put(frame, timeout=0.05)
                    return True
                except queue.Full:
                    continue
            return False
        self._stats.dropped_frames += put_dropping_oldest(self._queue, frame)
        return True

    def _capture_loop(self) -> None:
        delay = self.config.retry_initial_s
        while not self._stop.is_set():
            uri = self.config.source
            self._restart_source.clear()
            try:
                source = open_source(uri)
            except FileSourceError as exc:
                self._fail_source(exc)
                return
            except OmnidevError as exc:
                self._wait_for_camera(exc, delay)
                delay = min(delay * 2, self.config.retry_max_s)
                continue
            live = bool(getattr(source, "live", True))
            try:
                with source:
                    self.source_live = live
                    log.info("source %s open (%s)", uri, "live" if live else "recorded")
                    self.state = "running"
                    delay = self.config.retry_initial_s
                    for frame in source:
                        if not self._put(frame, live):
                            break
                        self._stats.frames += 1
                        if self._stop.is_set() or self._restart_source.is_set():
                            break
                    else:
                        self._wait_processed()  # every captured frame is processed
                        if self._stop.is_set():
                            return
                        self.state = "ended"
                        log.info("source %s ended after %d frames", uri, self._stats.frames)
                        self.ended.set()
                        self.finished.set()
                        return
            except Exception as exc:
                final = isinstance(exc, FileSourceError) or not live
                if final:
                    # A file's data ends here: process what came before, then stop;
                    # reopening would only replay the same frames.
                    self._wait_processed()
                    self._fail_source(exc)
                    return
                if not isinstance(exc, OmnidevError):  # OpenCV or driver errors: logged in full
                    log.exception("source %s failed", uri)
                self._drain()  # frames captured before the loss still count
                self._lost.set()
                self._wait_for_camera(exc, delay)
                delay = min(delay * 2, self.config.retry_max_s)

    def _fail_source(self, exc: BaseException) -> None:
        """A recorded source failed: stop the pipeline with its error (buttons released)."""
        msg = str(exc) if isinstance(exc, OmnidevError) else f"{self.config.source}: {exc!r}"
        self.fatal = msg
        self.source_failed = True
        self.state = "failed"
        if self.log_fatal:
            log.error("%s; not retrying (a file is not a camera that may come back)", msg)
        self._stop.set()
        self.finished.set()

    def _wait_processed(self) -> None:
        """Wait until the worker has processed (or the queue dropped) every captured frame."""
        while not self._stop.is_set():
            s = self._stats
            if s.processed + s.dropped_frames >= s.frames or not self._worker.is_alive():
                return
            time.sleep(0.002)

    def _drain(self, timeout: float = 1.0) -> None:
        """Wait until the worker has taken every queued frame (or ``timeout`` s)."""
        end = time.monotonic() + timeout
        while not self._queue.empty() and time.monotonic() < end and not self._stop.is_set():
            time.sleep(0.002)

    def _wait_for_camera(self, exc: BaseException, delay: float) -> None:
        if self._stop.is_set():
            return
        self.state = "waiting for camera"
        self._stats.camera_retries += 1
        log.warning("%s; retrying in %.1f s", exc, delay)
        self._stop.wait(delay)

    def _work_loop(self) -> None:
        try:
            while not self._stop.is_set():
                self.heartbeat = time.monotonic()
                if self._lost.is_set():
                    self._lost.clear()
                    self._on_lost()
                self._poll_buttons()
                if self._paused.is_set() and self.source_live is False:
                    self._stop.wait(0.05)  # a file waits where it is while paused
                    continue
                try:
                    frame = self._queue.get(timeout=0.05)
                except queue.Empty:
                    continue
                if not self._paused.is_set():
                    self._process(frame)
                self._stats.processed += 1
        finally:
            try:
                self.sink.close()
            except Exception:
                log.exception("closing sink %s", self.sink.name)
            if self.buttons_in is not None:
                self.buttons_in.close()
            if self._pending_buttons is not None and self._pending_buttons[0] is not None:
                self._pending_buttons[0].close()

    def _poll_buttons(self) -> None:
        """Take the button input's presses and releases to the sink (worker thread)."""
        if self.buttons_in is None:
            return
        try:
            events = self.buttons_in.poll()
        except ButtonInputError as exc:
            log.error("%s; going on without it", exc)
            self.buttons_in = None
            events = [(b, False) for b in sorted(self._held)]
        for button, down in events:
            if down:
                self._held.add(button)
            else:
                self._held.discard(button)
            if self._paused.is_set() or self.sink.closed:
                continue
            try:
                if down:
                    self.sink.press(button)
                else:
                    self.sink.release(button)
            except Exception as exc:
                self._stats.sink_errors += 1
                log.error("sink %s: %s %s failed: %s", self.sink.name, button, down, exc)

    def _on_lost(self) -> None:
        with self._lock:
            pending, self._pending = self._pending, None
            new_buttons, self._pending_buttons = self._pending_buttons, None
        if new_buttons is not None:
            if self.buttons_in is not None:
                self.buttons_in.close()
            self.buttons_in = new_buttons[0]
        self._held.clear()  # released below; a key still down counts again when pressed again
        if self.dwell is not None:
            self.dwell.reset()
        try:
            self.sink.release_all()
        except Exception:
            log.exception("releasing buttons on %s", self.sink.name)
        if pending is not None:
            tracker, filt, sink = pending
            self.tracker, self.filter = tracker, filt
            if sink is not None:
                old, self.sink = self.sink, sink
                old.close()
        self.tracker.reset()
        if self.filter is not None:
            self.filter.reset()
        self._size = None  # a reopened source may deliver another size

    def _process(self, frame: Frame) -> None:
        h, w = frame.image.shape[:2]
        if self._size is None:
            self._size = (w, h)
        elif self._size != (w, h):
            # Calibrations and trackers are tied to one frame size: stop rather than
            # move the pointer from a frame they cannot interpret (buttons are released
            # when the worker closes the sink).
            self.fatal = (
                f"{self.config.source}: frame {frame.index} is {w}x{h}, the stream was "
                f"{self._size[0]}x{self._size[1]}; stopping with all buttons released"
            )
            if self.log_fatal:
                log.error("%s", self.fatal)
            self._stop.set()
            self.finished.set()
            return
        try:
            sample = self.tracker.track(frame)
        except Exception as exc:
            self._stats.tracker_errors += 1
            log.warning("tracker %s failed on frame %d: %s", self.config.tracker, frame.index, exc)
            return
        if sample is None:
            if self.dwell is not None:
                self.dwell.reset()  # no cursor: the rest, if any, starts again
            if self.config.buttons.release_when_lost and self.sink.pressed:
                # target lost (laser off, landmarks gone): no button stays down; a key
                # still held presses again with the next position
                try:
                    self.sink.release_all()
                except Exception as exc:
                    self._stats.sink_errors += 1
                    log.error("sink %s: releasing buttons failed: %s", self.sink.name, exc)
            return
        x, y = sample.x, sample.y
        if self.filter is not None:
            x, y = self.filter(sample.timestamp_ns / 1e9, [sample.x, sample.y])
        sample = PointerSample(
            float(x),
            float(y),
            sample.timestamp_ns,
            sample.confidence,
            sample.buttons | frozenset(self._held),
            frame.index,
        )
        try:
            self.sink.emit(sample)
        except Exception as exc:
            # e.g. a USB host unplugged from the hidg gadget: keep going, log once
            self._stats.sink_errors += 1
            if not self._sink_failing:
                log.error("sink %s failed: %s (retrying with every frame)", self.sink.name, exc)
            self._sink_failing = True
            return
        if self._sink_failing:
            log.info("sink %s works again", self.sink.name)
            self._sink_failing = False
        if self.dwell is not None:
            rect = self.config.screen.screen
            t = sample.timestamp_ns / 1e9
            if self.dwell.update(t, sample.x * (rect.width - 1), sample.y * (rect.height - 1)):
                self.sink.click(self.dwell.button, sample=sample)
                self._dwell_clicks += 1
        done = time.monotonic_ns()
        self._stats.tracked += 1
        self._latency_ns.append(done - frame.monotonic_ns)
        self._times_ns.append(done)
        if self.on_sample is not None:
            self.on_sample(sample, done)

    @staticmethod
    def _make_dwell(config: DaemonConfig) -> DwellClicker | None:
        b = config.buttons
        return DwellClicker(b.dwell_radius_px, b.dwell_s, b.dwell_button) if b.dwell else None

    @staticmethod
    def _make_filter(config: DaemonConfig) -> OneEuroFilter | None:
        f = config.filter
        if f.kind == "none":
            return None
        return OneEuroFilter(f.min_cutoff, f.beta, f.d_cutoff, max_gap_s=f.max_gap_s or None)
