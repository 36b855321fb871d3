"""End-to-end pointer latency: the daemon pipeline on a 60 fps fixture into a real X server.

The pipeline (omnidev.daemon.pipeline) runs the blob fixture
(fixtures/blob/blob.avi, looped, delivered at 60 frames per second like a
camera) through the bright-blob tracker, the One Euro filter and the xtest
sink into an Xvfb started here. Latency of a frame = the moment the sink call
returned (XTest request processed by the server: XSync round trip done) minus
the frame's capture timestamp (when the source delivered it).

Figures (one run):
- latency_p50_ms, latency_p99_ms: over every frame of the run (target p99 < 5 ms).
- frames, dropped_frames, fps: what the pipeline saw.
- sink_us_per_event: the xtest sink's own cost per move (FakeInput + XSync).
- bare_xtest_us_per_event: the anchor: python-xlib's fake_input + sync with no omnidev code.
- sink_ratio_vs_bare: sink / anchor.

Inside a VM (a real 6.1 kernel under qemu TCG, as tests/vm; skipped with
``--quick``, without vng/qemu/kernel, or with OMNIDEV_BENCH_VM=0): the same
pipeline fed by vivid's video loop into the uinput sink, latency measured up to
the kernel's event timestamp (evdev, CLOCK_MONOTONIC). Reported, not held to the
target: the VM's CPU is emulated.
- vm_latency_p50_ms, vm_latency_p99_ms: capture -> kernel event timestamp.
- vm_sink_to_kernel_p50_us, vm_sink_to_kernel_p99_us: the uinput sink's own
  cost, from the call to the kernel's timestamp.
- vm_fps, vm_dropped_frames: what the emulated pipeline kept up with.
"""

from __future__ import annotations

import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from omnidev.daemon.config import parse_config  # noqa: E402
from omnidev.daemon.pipeline import Pipeline  # noqa: E402
from omnidev.screen import ScreenMapping  # noqa: E402
from omnidev.sinks.xtest_sink import XtestSink  # noqa: E402
from tests.xserver import xvfb  # noqa: E402

BLOB = ROOT / "fixtures" / "blob" / "blob.avi"


def _sink_cost_us(display: str, n: int) -> tuple[float, float]:
    """(omnidev xtest sink, bare python-xlib) median µs per move, interleaved in blocks."""
    import Xlib.display
    import Xlib.ext.xtest
    from Xlib import X

    sink = XtestSink(ScreenMapping.single(1920, 1080), display=display)
    d = Xlib.display.Display(display)
    ours: list[float] = []
    bare: list[float] = []
    block = 100
    try:
        for _ in range(n // block):
            t0 = time.perf_counter_ns()
            for i in range(block):
                sink.move((i % 97) / 96, (i % 89) / 88)
            t1 = time.perf_counter_ns()
            for i in range(block):
                Xlib.ext.xtest.fake_input(d, X.MotionNotify, x=(i * 19) % 1920, y=(i * 11) % 1080)
                d.sync()
            t2 = time.perf_counter_ns()
            ours.append((t1 - t0) / block / 1e3)
            bare.append((t2 - t1) / block / 1e3)
    finally:
        sink.close()
        d.close()
    return float(np.median(ours)), float(np.median(bare))


VM_TESTS = [
    "tests/vm/test_daemon.py::test_daemon_follows_vivid_camera_into_uinput",
    "tests/vm/test_uinput.py::test_sink_to_kernel_timestamp",
]


def _vm_figures() -> dict[str, Any]:
    """Boot the test VM for the two latency tests; their figures, or why there are none."""
    vng = shutil.which("vng", path=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    kernels = sorted(glob.glob("/boot/vmlinuz-*-amd64"))
    if not vng or not kernels or not shutil.which("qemu-system-x86_64"):
        return {"vm": "skipped: vng, qemu-system-x86_64 or /boot/vmlinuz-*-amd64 missing"}
    with tempfile.TemporaryDirectory(prefix="omnidev-bench-vm-") as out:
        script = ROOT / "tests" / "vm" / "run-in-vm.sh"
        cmd = [
            vng, "--run", kernels[-1], "--user", "root", "--disable-kvm", "--memory", "2G",
            "--rwdir", out, "--exec", f"{script} {out} {sys.executable} {' '.join(VM_TESTS)}",
        ]  # fmt: skip
        env = {**os.environ, "PATH": f"{Path(vng).parent}{os.pathsep}{os.environ['PATH']}"}
        subprocess.run(cmd, env=env, stdin=subprocess.DEVNULL, capture_output=True, timeout=1800)
        path = Path(out) / "figures.json"
        if not path.exists():
            return {"vm": "failed: the VM run wrote no figures (see tests/test_kernel_vm.py)"}
        figures = json.loads(path.read_text())
    renamed = {"vm_daemon_fps": "vm_fps", "vm_daemon_dropped_frames": "vm_dropped_frames"}
    kept = (
        "vm_latency_p50_ms",
        "vm_latency_p99_ms",
        "vm_sink_to_kernel_p50_us",
        "vm_sink_to_kernel_p99_us",
    )
    result: dict[str, Any] = {k: figures[k] for k in kept if k in figures}
    result.update({new: figures[old] for old, new in renamed.items() if old in figures})
    return result


def run(quick: bool = False) -> dict[str, Any]:
    seconds = 3.0 if quick else 12.0
    with xvfb(1920, 1080) as display:
        doc = {
            "source": {"uri": f"video:{BLOB}?loop=1&rate=60"},
            "tracker": {"name": "bright-blob", "options": {"press_area": 700}},
            "filter": {"kind": "one-euro"},
            "sink": {"name": "xtest", "options": {"display": display}},
            "screen": {"rect": "1920x1080+0+0"},
            "daemon": {"queue": 1},
        }
        config = parse_config(doc, Path("bench/pointer.py"))
        pipeline = Pipeline(config)
        pipeline.start()
        time.sleep(0.5)  # warm-up: first frames decode while caches fill
        skip = len(pipeline.latencies_ns())
        time.sleep(seconds)
        status = pipeline.status()
        lat = np.array(pipeline.latencies_ns()[skip:], np.float64) / 1e6
        pipeline.stop()
        sink_us, bare_us = _sink_cost_us(display, 1000 if quick else 5000)
    vm: dict[str, Any] = {}
    if not quick and os.environ.get("OMNIDEV_BENCH_VM", "1") != "0":
        vm = _vm_figures()
    return {
        "fixture": "fixtures/blob/blob.avi at 60 fps (looped)",
        "sink": "xtest -> Xvfb",
        "seconds": seconds,
        "frames": int(lat.size),
        "fps": status["fps"],
        "dropped_frames": status["dropped_frames"],
        "latency_p50_ms": round(float(np.percentile(lat, 50)), 3),
        "latency_p99_ms": round(float(np.percentile(lat, 99)), 3),
        "latency_max_ms": round(float(lat.max()), 3),
        "sink_us_per_event": round(sink_us, 1),
        "bare_xtest_us_per_event": round(bare_us, 1),
        "sink_ratio_vs_bare": round(sink_us / bare_us, 3),
        **vm,
    }
