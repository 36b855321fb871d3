"""The unwarping pipeline: read -> remap -> write, each stage on its own thread, in order.

Handling a frame takes three steps, and each runs on its own thread so that
they overlap on the cores the process is given:

1. **read** (thread ``read``): the source decodes the next frame (a video
   decoder may use more threads of its own);
2. **remap** (thread ``remap``): every view's maps are applied (OpenCV's
   ``cv2.remap``, which splits a large image over its own thread pool), and
   each result is converted to the layout its output takes
   (omnidev.outputs.pixels);
3. **write** (one thread per output, ``write:NAME``): the output encodes or
   sends the frame.

Stages hand frames on through bounded queues (``depth`` frames each), so a
slow stage holds the others back instead of filling the memory; every queue is
first-in first-out and every stage has one thread, so frames leave in the order
they came, each exactly once. With ``cpu_slots`` N, at most N stages work at
once (a semaphore held while decoding a frame, remapping it, encoding it): a
process given N cores (a batch worker of N threads) then uses N cores, not
the two or three the overlapping stages would take. The first exception in any stage stops all of
them and is raised by :func:`run` (the caller aborts the outputs); the GIL is
released inside decoding, remapping and encoding, which is where the time goes.
"""

from __future__ import annotations

import contextlib
import queue
import signal
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from omnidev.frame import Frame
from omnidev.outputs import Layout, Output
from omnidev.outputs.pixels import to_layout

Remap = Callable[[NDArray[np.uint8]], NDArray[np.uint8]]
_END = object()


@dataclass
class StageTime:
    """Time one stage's thread spent: working (wall, s) and on the CPU (s)."""

    busy_s: float = 0.0
    cpu_s: float = 0.0


@dataclass
class PipelineStats:
    """What :func:`run` measured."""

    frames: int = 0
    wall_s: float = 0.0
    stages: dict[str, StageTime] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "frames": self.frames,
            "wall_s": round(self.wall_s, 4),
            "fps": round(self.frames / self.wall_s, 3) if self.wall_s > 0 else None,
            "stages": {
                k: {"busy_s": round(v.busy_s, 4), "cpu_s": round(v.cpu_s, 4)}
                for k, v in self.stages.items()
            },
        }


class _StoppedError(Exception):
    """Another stage failed: this one leaves quietly."""


class _Pipeline:
    def __init__(self, depth: int) -> None:
        self.depth = depth
        self.stop = threading.Event()
        self.errors: list[BaseException] = []
        self.lock = threading.Lock()

    def fail(self, exc: BaseException) -> None:
        with self.lock:
            self.errors.append(exc)
        self.stop.set()

    def put(self, q: queue.Queue[Any], item: Any) -> None:
        while True:
            if self.stop.is_set():
                raise _StoppedError
            try:
                q.put(item, timeout=0.1)
                return
            except queue.Full:
                continue

    def get(self, q: queue.Queue[Any]) -> Any:
        while True:
            if self.stop.is_set():
                raise _StoppedError
            try:
                return q.get(timeout=0.1)
            except queue.Empty:
                continue


def run(
    frames: Iterable[Frame],
    layout: Layout,
    remaps: Sequence[Remap],
    outputs: Sequence[Output],
    *,
    limit: int | None = None,
    check: Callable[[Frame], None] | None = None,
    on_written: Callable[[int], None] | None = None,
    depth: int = 4,
    cpu_slots: int | None = None,
) -> PipelineStats:
    """Unwarp ``frames`` (images in ``layout``) into ``outputs``: output i gets ``remaps[i]``.

    ``check(frame)`` runs on each frame as it is read (raise to stop, e.g. on a
    wrong size); ``on_written(n)`` is called from the first output's thread
    after it has written n frames (a progress bar). Stops after ``limit``
    frames. ``cpu_slots``: at most this many stages work at once (None: all
    three overlap). Returns the frame count and per-stage times; raises the
    first error of any stage.
    """
    if len(remaps) != len(outputs):
        raise ValueError("one remap per output")
    if cpu_slots is not None and cpu_slots < 1:
        raise ValueError("cpu_slots must be >= 1")
    slots = threading.BoundedSemaphore(cpu_slots) if cpu_slots is not None else None

    def working() -> contextlib.AbstractContextManager[Any]:
        return slots if slots is not None else contextlib.nullcontext()

    p = _Pipeline(depth)
    stats = PipelineStats()
    q_read: queue.Queue[Any] = queue.Queue(depth)
    q_out: list[queue.Queue[Any]] = [queue.Queue(depth) for _ in outputs]
    names = ["read", "remap", *(f"write:{o.name}" for o in outputs)]
    stats.stages = {n: StageTime() for n in names}
    written = [0] * len(outputs)

    done = {n: threading.Event() for n in names}

    def timed(name: str, body: Callable[[StageTime], None]) -> Callable[[], None]:
        def main() -> None:
            st = stats.stages[name]
            cpu0 = time.thread_time()
            try:
                body(st)
            except _StoppedError:
                pass
            except BaseException as exc:  # any failure stops every stage
                p.fail(exc)
            finally:
                st.cpu_s = time.thread_time() - cpu0
                done[name].set()

        return main

    def read(st: StageTime) -> None:
        n = 0
        it = iter(frames)
        while limit is None or n < limit:
            with working():
                t0 = time.perf_counter()
                frame = next(it, None)
                st.busy_s += time.perf_counter() - t0
            if frame is None:
                break
            if check is not None:
                check(frame)
            p.put(q_read, frame)
            n += 1
        p.put(q_read, _END)

    def remap(st: StageTime) -> None:
        while True:
            item = p.get(q_read)
            if item is _END:
                for q in q_out:
                    p.put(q, _END)
                return
            with working():
                t0 = time.perf_counter()
                views: dict[tuple[int, str], NDArray[np.uint8]] = {}
                results = []
                for i, (fn, out) in enumerate(zip(remaps, outputs, strict=True)):
                    key = (id(fn), out.layout)
                    if key not in views:
                        image = fn(item.image)
                        if out.layout != layout:
                            image = to_layout(image, layout, out.layout)
                        views[key] = image
                    results.append((i, views[key]))
                st.busy_s += time.perf_counter() - t0
            for i, image in results:
                p.put(q_out[i], Frame(image, item.timestamp_ns, item.index))

    def writer(i: int) -> Callable[[StageTime], None]:
        def body(st: StageTime) -> None:
            out = outputs[i]
            while True:
                item = p.get(q_out[i])
                if item is _END:
                    return
                with working():
                    t0 = time.perf_counter()
                    out.write(item)
                    st.busy_s += time.perf_counter() - t0
                written[i] += 1
                if i == 0 and on_written is not None:
                    on_written(written[0])

        return body

    threads = [
        threading.Thread(target=timed("read", read), name="read", daemon=True),
        threading.Thread(target=timed("remap", remap), name="remap", daemon=True),
        *(
            threading.Thread(target=timed(names[2 + i], writer(i)), name=names[2 + i], daemon=True)
            for i in range(len(outputs))
        ),
    ]
    t0 = time.perf_counter()
    try:
        _start(threads)
        for t in threads:
            while not done[t.name].is_set() and not p.stop.is_set():
                done[t.name].wait(0.2)
    except BaseException:  # Ctrl-C or SIGTERM in the main thread: stop the stages, re-raise
        p.stop.set()
        _wait([done[t.name] for t in threads if t.ident is not None], p.stop)
        raise
    signalled = _wait(list(done.values()), p.stop)  # the others, after a failure
    if signalled is not None:
        raise signalled
    stats.wall_s = time.perf_counter() - t0
    if p.errors:
        raise p.errors[0]
    stats.frames = written[0] if outputs else 0
    return stats


_HELD = {signal.SIGINT, signal.SIGTERM}


def _start(threads: list[threading.Thread]) -> None:
    """Start every stage with SIGINT and SIGTERM held back, so that the exception a
    signal raises in the main thread finds all of them started (and stops them all),
    never a read stage decoding while the caller closes the source."""
    main = threading.current_thread() is threading.main_thread()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD) if main else None
    try:
        for t in threads:
            t.start()
    finally:
        if old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _wait(
    stages: list[threading.Event], stop: threading.Event, timeout_s: float = 5.0
) -> BaseException | None:
    """Wait until the stages have left their work (each sets its event last).

    Not ``Thread.join``: on Python 3.11 a join interrupted by a signal (Ctrl-C,
    SIGTERM raised in the main thread) can mark a running thread stopped, and the
    caller then closed the source under a stage still decoding in it (a crash or
    a hang at exit, about one interrupted run in 100). A signal that arrives
    meanwhile stops the stages and is returned, to be raised once they are out.
    A stage blocked in a device read for longer than ``timeout_s`` is left
    behind (a daemon thread).
    """
    deadline = time.monotonic() + timeout_s
    signalled: BaseException | None = None
    for d in stages:
        while not d.is_set() and (left := deadline - time.monotonic()) > 0:
            try:
                d.wait(left)
            except BaseException as exc:  # a second Ctrl-C while the stages stop
                stop.set()
                signalled = signalled or exc
    return signalled
