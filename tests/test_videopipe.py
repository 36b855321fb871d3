"""omnidev.videopipe: order, count, limits and failures of the threaded pipeline."""

from __future__ import annotations

import signal
import threading
import time

import numpy as np
import pytest

from omnidev.errors import OutputError, SourceError
from omnidev.frame import Frame
from omnidev.outputs import OutputBase
from omnidev.videopipe import run


class Collect(OutputBase):
    """An output that keeps what it gets (optionally slowly, optionally failing at a frame)."""

    def __init__(self, name: str, delay_s: float = 0.0, fail_at: int | None = None) -> None:
        self.name = name
        self.layout = "bgr"
        self.frames = 0
        self.got: list[tuple[int, int, int]] = []
        self.delay_s = delay_s
        self.fail_at = fail_at
        self.thread: str | None = None

    def write(self, frame: Frame) -> None:
        if self.fail_at is not None and frame.index == self.fail_at:
            raise OutputError(f"{self.name}: disk full at frame {frame.index}")
        time.sleep(self.delay_s)
        self.thread = threading.current_thread().name
        self.got.append((frame.index, frame.timestamp_ns, int(frame.image[0, 0, 0])))
        self.frames += 1


def frames(n: int, fail_at: int | None = None):
    for i in range(n):
        if i == fail_at:
            raise SourceError(f"src: frame {i} is corrupt")
        yield Frame(np.full((4, 6, 3), i % 256, np.uint8), 1000 + i, i)


def plus(k: int):
    return lambda img: (img.astype(np.int64) + k).clip(0, 255).astype(np.uint8)


def test_every_frame_once_in_order_per_output_with_its_own_view():
    slow, fast = Collect("slow", delay_s=0.002), Collect("fast")
    stats = run(frames(200), "bgr", [plus(1), plus(2)], [slow, fast], depth=3)
    assert stats.frames == 200
    assert slow.got == [(i, 1000 + i, (i % 256) + 1) for i in range(200)]
    assert fast.got == [(i, 1000 + i, min((i % 256) + 2, 255)) for i in range(200)]
    assert slow.thread == "write:slow" and fast.thread == "write:fast"
    assert set(stats.stages) == {"read", "remap", "write:slow", "write:fast"}
    assert stats.stages["write:slow"].busy_s >= 200 * 0.002 * 0.9


def test_limit_stops_reading():
    out = Collect("o")
    assert run(frames(50), "bgr", [plus(0)], [out], limit=7).frames == 7
    assert [g[0] for g in out.got] == list(range(7))


def test_a_failing_output_stops_everything_and_its_error_is_raised():
    bad, good = Collect("bad", fail_at=13), Collect("good", delay_s=0.001)
    with pytest.raises(OutputError, match="disk full at frame 13"):
        run(frames(10_000), "bgr", [plus(0), plus(0)], [bad, good])
    assert len(bad.got) == 13
    assert len(good.got) < 10_000  # it stopped early


def test_a_source_error_is_raised():
    out = Collect("o")
    with pytest.raises(SourceError, match="frame 5 is corrupt"):
        run(frames(20, fail_at=5), "bgr", [plus(0)], [out])
    # the outputs are aborted after an error: what reached them is an in-order prefix
    assert [g[0] for g in out.got] == list(range(len(out.got))) and len(out.got) <= 5


def test_check_rejects_a_frame():
    def check(frame: Frame) -> None:
        if frame.index == 3:
            raise SourceError("src frame 3 is 5x4; the calibration is for 6x4")

    with pytest.raises(SourceError, match="frame 3 is 5x4"):
        run(frames(10), "bgr", [plus(0)], [Collect("o")], check=check)


class Active:
    """Counts the stages working at once (each stage's work is a 1 ms sleep)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.now = 0
        self.most = 0

    def work(self) -> None:
        with self.lock:
            self.now += 1
            self.most = max(self.most, self.now)
        time.sleep(0.001)
        with self.lock:
            self.now -= 1


class Busy(Collect):
    def __init__(self, name: str, active: Active) -> None:
        super().__init__(name)
        self.active = active

    def write(self, frame: Frame) -> None:
        self.active.work()
        super().write(frame)


def test_cpu_slots_bound_the_stages_working_at_once():
    def source(active: Active, n: int):
        for f in frames(n):
            active.work()
            yield f

    def remap(active: Active):
        def fn(img):
            active.work()
            return img

        return fn

    most = {}
    for slots in (None, 1, 2):
        active = Active()
        outs = [Busy("a", active), Busy("b", active)]
        stats = run(source(active, 60), "bgr", [remap(active)] * 2, outs, cpu_slots=slots)
        assert stats.frames == 60 and [g[0] for g in outs[1].got] == list(range(60))
        most[slots] = active.most
    # unbounded, the read, remap and two write stages overlap; one slot: one at a time
    assert most[None] >= 3 and most[1] == 1 and most[2] == 2
    with pytest.raises(ValueError, match="cpu_slots"):
        run(frames(1), "bgr", [plus(0)], [Collect("o")], cpu_slots=0)


class SignalledError(Exception):
    """What the test's signal handler raises in the main thread (as Ctrl-C would)."""


def raise_signalled(signum, frame):
    raise SignalledError


def slow_source(decoding: threading.Event, first_s: float, then_s: float):
    """frames(1000), each decode a sleep (GIL released, as cv2's) with ``decoding`` set."""
    for f in frames(1000):
        decoding.set()
        time.sleep(then_s if f.index else first_s)
        decoding.clear()
        yield f


def test_a_signal_returns_only_after_the_stages_left_their_work():
    """A signal raised in the main thread while it waits: run() re-raises only once the
    read stage, here in a slow decode (GIL released, as cv2's), has come out of it.

    With ``Thread.join`` (Python 3.11) the interrupted join marked the decoding thread
    stopped, run() returned at once and the caller closed the source under it: a crash
    at exit in about one of 100 interrupted ``omnidev unwarp`` runs.
    """
    decoding = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers run in the main thread only; this test runs in another")
    old = signal.signal(signal.SIGUSR1, raise_signalled)
    main = threading.main_thread().ident
    assert main is not None
    timer = threading.Timer(0.5, lambda: signal.pthread_kill(main, signal.SIGUSR1))
    try:
        timer.start()
        t0 = time.monotonic()
        with pytest.raises(SignalledError):
            # the first decode (1.5 s) is still on at the signal (0.5 s)
            run(slow_source(decoding, 1.5, 0.3), "bgr", [plus(0)], [Collect("o")])
        in_decode = decoding.is_set()
        waited = time.monotonic() - t0
    finally:
        timer.cancel()
        signal.signal(signal.SIGUSR1, old)
    assert not in_decode
    assert 1.4 <= waited < 5.0  # it waited for the decode (1.5 s), not the 5 s limit


def test_a_signal_while_the_stages_start_stops_them_all(monkeypatch):
    """SIGTERM arriving while run() starts its stage threads (the read stage already
    decoding): it is held back until all have started, then stops every one, and run()
    re-raises once the decode is over. Before, it left the pipeline running under a
    caller that closed the source: a hang in ``sws_freeContext`` at exit."""
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers run in the main thread only; this test runs in another")
    decoding = threading.Event()
    start = threading.Thread.start
    main = threading.main_thread().ident
    assert main is not None

    def start_with_signal(self):
        if self.name == "remap":  # the read stage runs: a SIGTERM lands now
            assert decoding.wait(2.0)
            signal.pthread_kill(main, signal.SIGTERM)
            time.sleep(0.05)  # an unheld signal is raised here, inside Thread.start
        start(self)

    monkeypatch.setattr(threading.Thread, "start", start_with_signal)
    old = signal.signal(signal.SIGTERM, raise_signalled)
    outs = [Collect("o")]
    try:
        with pytest.raises(SignalledError):
            run(slow_source(decoding, 0.8, 0.8), "bgr", [plus(0)], outs)
        in_decode = decoding.is_set()
    finally:
        signal.signal(signal.SIGTERM, old)
    assert not in_decode
    stages = {"read", "remap", "write:o"}
    deadline = time.monotonic() + 2.0  # out of their work; the threads' own exit follows
    while (names := {t.name for t in threading.enumerate()} & stages) and (
        time.monotonic() < deadline
    ):
        time.sleep(0.01)
    assert not names, f"stages still running: {names}"
