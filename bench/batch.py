"""Batch unwarping on Dask: 1 and 2 workers against single-process ``omnidev unwarp``, same run.

Input (made once per run, or reused from $OMNIDEV_BENCH_CACHE): ``videos`` H.264
clips (4, or 2 with --quick) of ``frames`` frames each (480: 19 s at 25 fps,
or 96 with --quick), 960x960 4:2:0, GOP 48 with 2 B-frames (as a surveillance or dash
camera records), each omnidev.sim's room through an ideal 190-degree
equidistant fisheye looking up, turned 0.4 degrees further each frame, with
sensor noise (sigma 2, one of 17 noise fields per frame, in turn). Output:
``panorama:1024x256`` as H.264 (omnidev's .mp4 default: libx264 veryfast
crf 20).

Cases, each the whole command a user runs, timed from process start to exit
(so Python's start, the cluster's start and the maps count), interleaved over
``reps`` repetitions ($OMNIDEV_BENCH_REPS, default 2, or 1 with --quick), medians:

- ``single``: ``omnidev unwarp`` once per input, one after the other, as a shell
  loop would (the anchor: what a user has without ``omnidev batch``), with its
  default threads (the usable cores); ``single_1t``: the same with --threads 1;
  ``single_1t_p2``: two such loops at once, half the inputs each (``xargs -P 2``,
  what a user might script instead of a cluster). ``pin`` / ``pin_p2``: the
  ``single_1t`` loop pinned to one core (``taskset``), and two such loops pinned
  to the two cores at once: what this machine gives two independent one-core
  processes, the ceiling of any 2-worker scheme here (a ``--threads 1`` process
  left unpinned spreads its decoder, encoder and stage threads over both cores,
  so ``single_1t_p2`` is no ceiling).
- ``batch_w1`` / ``batch_w2``: ``omnidev batch unwarp`` over all inputs on a
  local cluster of 1 / 2 worker processes (one thread each, ``--range-frames
  48``: one task per 48 frames). A task of one thread uses one core: its
  decoder and encoder run on one thread, and its read, remap and write stages
  take turns (omnidev.videopipe's ``cpu_slots``) instead of overlapping on
  the other core.

Figures: ``*_fps`` (frames / median wall), ``*_job_fps`` (frames / the job's
own wall time from its --json report: without Python's and the cluster's
start), ``ratio_w2_vs_w1`` (whole commands; target >= 1.7 on 2 idle cores),
``ratio_parallel_ceiling`` (``pin`` over ``pin_p2``: the machine's own
2-core scaling, which ``ratio_w2_vs_w1`` cannot exceed), ``ratio_w2_vs_xargs_p2``
(``single_1t_p2``'s wall over ``w2``'s: above 1, the batch beats two plain loops),
``ratio_w2_vs_w1_job`` (the jobs' own wall times: without the cluster's start,
which does not shrink with more workers), ``ratio_w1_vs_single`` and
``ratio_w2_vs_single`` (against the anchor), ``ratio_w1_vs_single_1t``,
``job_cores_w1`` / ``job_cores_w2`` (the range tasks' pipeline CPU seconds
over the job's wall time: the cores a job kept busy, at most 1 / 2),
``startup_s_w1`` / ``startup_s_w2`` (command wall minus job wall, medians:
Python's start, the local cluster's start and stop). ``load_avg_1min`` holds
the 1-minute load average at the start of every timed command, per case, and
``bench_s`` the bench's own wall time. The cost model's inputs, from the 2-worker job's report
(docs/batch.md): per-frame CPU ms of decoding, remapping and encoding, per-range
task overhead (``task_setup_ms``: opening, seeking, starting and closing the
encoder, wall time outside the frame pipeline), per-task bytes read and
written, the join's time per output, the maps' bytes (moved once per worker),
and ``noop_task_ms``: the round trip of a task that does nothing through the
same kind of cluster (``client.map`` of 400 no-op tasks, wall / tasks, 2
workers). The machine is shared: ``load_avg_1min_*`` says how busy it was.
``projection_10000h``: the archive cost figures computed from these (see
docs/batch.md for the formula): the stages' CPU ms per frame plus the task's
fixed costs over a 250-frame range (``task_setup_ms`` is wall time, so a loaded
machine overstates it).
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import cv2
import numpy as np

SIZE = 960
VIEW = "panorama:1024x256"
RANGE = 48
DEFAULT_RANGE = 250  # omnidev batch unwarp --range-frames default


def _input(data: Path, videos: int, frames: int) -> tuple[list[Path], Path]:
    import av

    from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
    from omnidev.fisheye.camfile import write_camera_file
    from omnidev.fisheye.models import IdealFisheye
    from omnidev.sim.fisheye import EquidistantFisheyeCamera
    from omnidev.sim.render import render_omni
    from omnidev.sim.scene import RoomScene

    f = 0.5 * SIZE / math.radians(95)
    c = (SIZE - 1) / 2
    cam = data / "fisheye.yml"
    if not cam.exists():
        lens = IdealFisheye("equidistant", f, c, c)
        write_camera_file(cam, FisheyeCamera(lens, (SIZE, SIZE), MOUNTS["up"], 95.0))
    paths = [data / f"clip{k}-{frames}-n17.mp4" for k in range(videos)]
    todo = [p for p in paths if not p.exists()]
    if not todo:
        return paths, cam
    sim = EquidistantFisheyeCamera(f, (SIZE, SIZE), (c, c), math.radians(95))
    rng = np.random.default_rng(1)
    noise = [2 * rng.standard_normal((SIZE, SIZE, 3), dtype=np.float32) for _ in range(17)]
    for k, path in enumerate(paths):
        if path.exists():
            continue
        base = render_omni(sim, RoomScene(seed=100 + k), supersample=1)
        tmp = path.with_suffix(".part.mp4")
        with av.open(str(tmp), "w") as out:
            stream = out.add_stream("libx264", rate=25)
            stream.width = stream.height = SIZE
            stream.pix_fmt = "yuv420p"
            stream.options = {"g": "48", "bf": "2", "preset": "veryfast", "crf": "20"}
            for i in range(frames):
                turn = cv2.getRotationMatrix2D((c, c), 0.4 * i, 1.0)
                turned = np.asarray(cv2.warpAffine(base, turn, (SIZE, SIZE)), np.float32)
                noisy = turned + noise[i % len(noise)]
                frame = av.VideoFrame.from_ndarray(
                    np.clip(noisy, 0, 255).astype(np.uint8), format="bgr24"
                )
                for packet in stream.encode(frame):
                    out.mux(packet)
            for packet in stream.encode():
                out.mux(packet)
        tmp.rename(path)
    return paths, cam


def _timed(cmd: list[str]) -> tuple[float, str]:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:3])}... failed: {p.stderr.strip()[-500:]}")
    return wall, p.stdout


def _loop(cmds: list[list[str]], core: int | None = None) -> None:
    """Run the commands one after the other (``core``: each pinned to that core)."""
    for cmd in cmds:
        _timed(cmd if core is None else ["taskset", "-c", str(core), *cmd])


def _noop_ms(workers: int, tasks: int = 400) -> float:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from omnidev.batch.runner import start_local_cluster
    from omnidev.batch.tasks import noop_task

    cluster, client = start_local_cluster(workers)
    try:
        client.gather(client.map(noop_task, range(20), key=[f"warm-{i}" for i in range(20)]))
        t0 = time.perf_counter()
        futures = client.map(noop_task, range(tasks), key=[f"noop-{i}" for i in range(tasks)])
        client.gather(futures)
        return 1000 * (time.perf_counter() - t0) / tasks
    finally:
        client.close()
        cluster.close()


def run(quick: bool = False) -> dict[str, Any]:
    videos, frames = (2, 96) if quick else (4, 480)
    t_bench = time.perf_counter()
    reps = int(os.environ.get("OMNIDEV_BENCH_REPS", 1 if quick else 2))
    omnidev_bin = str(Path(sys.executable).parent / "omnidev")
    cache = os.environ.get("OMNIDEV_BENCH_CACHE")
    cores = sorted(os.sched_getaffinity(0))
    result: dict[str, Any] = {
        "input": f"{videos} videos x {frames} frames {SIZE}x{SIZE} H.264 GOP 48, -> {VIEW} H.264",
        "cores": len(cores),
        "reps": reps,
        "load_avg_1min_start": round(os.getloadavg()[0], 2),
    }
    with tempfile.TemporaryDirectory(prefix="omnidev-bench-batch-") as tmp:
        work = Path(tmp)
        data = Path(cache) if cache else work
        data.mkdir(parents=True, exist_ok=True)
        paths, cam = _input(data, videos, frames)
        total = videos * frames
        walls: dict[str, list[float]] = {
            "single": [], "single_1t": [], "single_1t_p2": [], "pin": [], "pin_p2": [],
            "w1": [], "w2": [],
        }  # fmt: skip
        jobs: dict[str, list[dict[str, Any]]] = {"w1": [], "w2": []}
        load: dict[str, list[float]] = {k: [] for k in walls}
        for rep in range(reps):
            for case in ("single", "w1", "w2", "single_1t", "single_1t_p2", "pin", "pin_p2"):
                out = work / f"out-{case}-{rep}"
                load[case].append(round(os.getloadavg()[0], 2))
                if not case.startswith("w"):
                    out.mkdir()
                    cmds = []
                    for p in paths:
                        cmd = [omnidev_bin, "unwarp", str(p), "--camera", str(cam),
                               "--view", VIEW, "-o", str(out / p.name)]  # fmt: skip
                        if case != "single":
                            cmd += ["--threads", "1"]
                        cmds.append(cmd)
                    t0 = time.perf_counter()
                    if case.endswith("_p2"):  # xargs -P 2: two loops, half the inputs each
                        pin = case == "pin_p2"
                        halves = [cmds[0::2], cmds[1::2]]
                        where = [cores[0], cores[-1]] if pin else [None, None]
                        with ThreadPoolExecutor(2) as pool:
                            list(pool.map(_loop, halves, where))
                    else:
                        _loop(cmds, cores[0] if case == "pin" else None)
                    walls[case].append(time.perf_counter() - t0)
                    continue
                cmd = [omnidev_bin, "batch", "unwarp", *map(str, paths), "--camera", str(cam),
                       "--view", VIEW, "--out", str(out), "--workers", case[1:],
                       "--range-frames", str(RANGE), "--json", "--no-progress"]  # fmt: skip
                wall, stdout = _timed(cmd)
                report = json.loads(stdout.strip().splitlines()[-1])
                if report["failed"] or sum(u["frames"] for u in report["inputs"]) != total:
                    raise RuntimeError(f"batch {case}: {report}")
                walls[case].append(wall)
                jobs[case].append(report)
        med = {k: statistics.median(v) for k, v in walls.items()}
        job_wall = {k: statistics.median(r["wall_s"] for r in v) for k, v in jobs.items()}
        for k in ("single", "single_1t", "single_1t_p2"):
            result[f"{k}_fps"] = round(total / med[k], 2)
        result["pin_fps"] = round(total / med["pin"], 2)
        result["pin_p2_fps"] = round(total / med["pin_p2"], 2)
        result["ratio_parallel_ceiling"] = round(med["pin"] / med["pin_p2"], 3)
        result["ratio_w2_vs_xargs_p2"] = round(med["single_1t_p2"] / med["w2"], 3)
        for k in ("w1", "w2"):
            result[f"batch_{k}_fps"] = round(total / med[k], 2)
            result[f"batch_{k}_job_fps"] = round(total / job_wall[k], 2)
        result["ratio_w2_vs_w1"] = round(med["w1"] / med["w2"], 3)
        result["ratio_w2_vs_w1_job"] = round(job_wall["w1"] / job_wall["w2"], 3)
        result["ratio_w1_vs_single"] = round(med["single"] / med["w1"], 3)
        result["ratio_w2_vs_single"] = round(med["single"] / med["w2"], 3)
        result["ratio_w1_vs_single_1t"] = round(med["single_1t"] / med["w1"], 3)
        for k in ("w1", "w2"):
            starts = [w - r["wall_s"] for w, r in zip(walls[k], jobs[k], strict=True)]
            result[f"startup_s_{k}"] = round(statistics.median(starts), 2)
            cpu = [
                sum(r["costs"][f"{st}_cpu_s"] for st in ("read", "remap", "write")) for r in jobs[k]
            ]
            result[f"job_cores_{k}"] = round(
                statistics.median(c / r["wall_s"] for c, r in zip(cpu, jobs[k], strict=True)), 2
            )
        result["wall_s"] = {k: [round(x, 2) for x in v] for k, v in walls.items()}
        result["load_avg_1min"] = load
        c = jobs["w2"][-1]["costs"]
        n, tasks = c["frames"], c["range_tasks"]
        model = {
            "decode_cpu_ms_per_frame": round(1000 * c["read_cpu_s"] / n, 3),
            "remap_cpu_ms_per_frame": round(1000 * c["remap_cpu_s"] / n, 3),
            "encode_cpu_ms_per_frame": round(1000 * c["write_cpu_s"] / n, 3),
            "task_wall_ms_per_frame": round(1000 * c["task_wall_s"] / n, 3),
            "range_tasks": int(tasks),
            "task_setup_ms": round(1000 * c["task_setup_s"] / tasks, 1),
            "read_bytes_per_task": int(c["read_bytes"] / tasks),
            "segment_bytes_per_task": int(c["segment_bytes"] / tasks),
            "join_ms_per_output": round(1000 * c["join_s"] / max(1, c["join_tasks"]), 1),
            "index_tasks": int(c["index_tasks"]),
            "maps_bytes": _maps_bytes(cam),
        }
        result["cost_model"] = model
    result["noop_task_ms"] = round(_noop_ms(2), 3)
    # per frame: the pipeline stages' CPU time (not their wall time, which a
    # loaded machine stretches) plus each task's fixed costs spread over a range
    # of the default length (docs/batch.md)
    cpu_ms = sum(model[f"{k}_cpu_ms_per_frame"] for k in ("decode", "remap", "encode"))
    per_frame_s = (
        cpu_ms + (model["task_setup_ms"] + result["noop_task_ms"]) / DEFAULT_RANGE
    ) / 1000
    archive_frames = 10_000 * 3600 * 25
    core_hours = archive_frames * per_frame_s / 3600
    result["projection_10000h"] = {
        "frames": archive_frames,
        "core_seconds_per_frame": round(per_frame_s, 5),
        "core_hours": round(core_hours),
        "days_on_workers": {n: round(core_hours / n / 24, 1) for n in (2, 16, 64, 256)},
    }
    result["load_avg_1min_end"] = round(os.getloadavg()[0], 2)
    result["bench_s"] = round(time.perf_counter() - t_bench, 1)
    return result


def _maps_bytes(cam: Path) -> int:
    import omnidev
    from omnidev.viewspec import parse_view

    maps = omnidev.build_maps(omnidev.load_camera(cam), parse_view(VIEW))
    return int(maps.map_x.nbytes + maps.map_y.nbytes + maps.valid.nbytes)
