"""Running a batch job on a Dask cluster: what the client does (docs/batch.md).

A job goes through its inputs in five kinds of tasks (omnidev.batch.tasks):

1. **maps**: one per camera and view, ``build_maps`` of that pair. Its result
   stays on the cluster and is moved to each worker once; Dask recomputes it
   if the worker holding it is lost.
2. **index**: one per video, its packet headers read and its frames cut into
   ranges at keyframes (omnidev.batch.avrange).
3. **range**: one per range of a video: decode, unwarp into every view,
   encode one segment file per view.
4. **join**: one per video once its ranges are done: each view's segments
   copied into the output file.
5. **images**: one per chunk of images of one camera and set of views.

The client submits tasks in a bounded window (a few per worker thread), so
an archive of any size keeps the scheduler's and the client's memory small,
records every finished task in the job manifest (omnidev.batch.journal)
before it counts it, and shows the frames done as a progress bar. Inputs that
are already done are skipped, and ranges already done are not run again. A
task whose worker is lost is run again by Dask elsewhere (up to Dask's
``distributed.scheduler.allowed-failures``, 3 by default); an input that fails
is reported on one line naming it, and the others go on.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import time
import uuid
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from omnidev.batch import tasks
from omnidev.batch.avrange import FrameRange, VideoIndex
from omnidev.batch.inputs import (
    BadInput,
    BatchInput,
    common_root,
    find_collisions,
    output_path,
)
from omnidev.batch.journal import Journal, JournalState, file_hash, unit_key
from omnidev.calibfile import load_camera
from omnidev.camera import Maps, build_maps
from omnidev.errors import OmnidevError
from omnidev.viewspec import parse_view


@dataclass(frozen=True)
class Settings:
    """How a job unwarps and writes (the ``omnidev batch unwarp`` options).

    ``range_frames`` is the target length of a video range (frames; ranges
    start at keyframes and are as equal as those allow), ``images_per_task``
    the images of one task, ``task_threads`` the cores each task keeps busy
    (its codecs' and OpenCV's threads, and its pipeline stages working at once;
    one per Dask worker thread).
    """

    interpolation: str = "linear"
    video_suffix: str = ".mp4"
    image_suffix: str = ".png"
    encode: tuple[tuple[str, str], ...] = ()
    camera_options: tuple[tuple[str, str], ...] = ()
    range_frames: int = 250
    images_per_task: int = 16
    task_threads: int = 1
    fps: float | None = None
    force: bool = False
    keep_segments: bool = False

    def output_fields(self) -> dict[str, Any]:
        """The settings that change what is written (part of each unit's key)."""
        return {
            "interpolation": self.interpolation,
            "video_suffix": self.video_suffix,
            "image_suffix": self.image_suffix,
            "encode": sorted(self.encode),
            "camera_options": sorted(self.camera_options),
            "range_frames": self.range_frames,
            "task_threads": self.task_threads,
            "fps": self.fps,
        }


@dataclass
class UnitReport:
    """One input's line of the summary."""

    input: str
    kind: str
    status: str = "pending"  # ok | skipped (done before) | failed | pending (interrupted)
    frames: int = 0
    ranges: int = 0
    ranges_before: int = 0
    ranges_run: int = 0
    outputs: list[str] = field(default_factory=list)
    error: str = ""
    seconds: float = 0.0


@dataclass
class JobReport:
    """What a job did: per input, and the measured costs (the cost model's inputs).

    ``costs`` sums over the tasks run now: ``frames``, CPU seconds per stage
    (``read_cpu_s``, ``remap_cpu_s``, ``write_cpu_s``), ``task_wall_s`` (the
    range tasks' wall time), ``task_setup_s`` (their time outside the
    pipeline), ``read_bytes``, ``segment_bytes``, ``join_s``, ``join_bytes``,
    and counts of tasks by kind.
    """

    inputs: list[UnitReport]
    wall_s: float
    workers: int
    threads: int
    maps_built: int
    costs: dict[str, float]
    interrupted: bool = False

    @property
    def failed(self) -> list[UnitReport]:
        return [u for u in self.inputs if u.status == "failed"]

    def as_dict(self) -> dict[str, Any]:
        return {
            "inputs": [asdict(u) for u in self.inputs],
            "wall_s": round(self.wall_s, 4),
            "workers": self.workers,
            "threads": self.threads,
            "maps_built": self.maps_built,
            "costs": {k: round(v, 6) for k, v in self.costs.items()},
            "interrupted": self.interrupted,
            "ok": sum(u.status == "ok" for u in self.inputs),
            "skipped": sum(u.status == "skipped" for u in self.inputs),
            "failed": len(self.failed),
        }


@dataclass
class _Unit:
    item: BatchInput | None
    report: UnitReport
    key: str = ""
    outputs: list[Path] = field(default_factory=list)
    map_keys: list[str] = field(default_factory=list)
    camera_size: tuple[int, int] = (0, 0)
    index: VideoIndex | None = None
    todo: set[int] = field(default_factory=set)
    done: dict[int, dict[str, Any]] = field(default_factory=dict)
    t0: float = 0.0

    @property
    def failed(self) -> bool:
        return self.report.status == "failed"


@dataclass(frozen=True)
class _Work:
    kind: str  # maps | index | range | join | images
    units: tuple[int, ...]
    frames: FrameRange | None = None
    map_key: str = ""


Say = Callable[[str], None]


def _stderr(line: str) -> None:
    tqdm.write(line, file=sys.stderr)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def run_job(
    inputs: Sequence[BatchInput],
    bad: Sequence[BadInput],
    out_dir: Path,
    settings: Settings,
    client: Any,
    *,
    progress: bool = True,
    say: Say = _stderr,
) -> JobReport:
    """Run a batch job on ``client`` (a ``distributed.Client``); see the module docstring.

    Each bad input, and each input that fails, is reported through ``say`` as
    one line naming it. Raises :class:`KeyboardInterrupt` after recording what
    finished when interrupted (the report is then attached as
    ``exc.report``).
    """
    return _Job(inputs, bad, Path(out_dir).resolve(), settings, client, progress, say).run()


class _Job:
    def __init__(
        self,
        inputs: Sequence[BatchInput],
        bad: Sequence[BadInput],
        out_dir: Path,
        settings: Settings,
        client: Any,
        progress: bool,
        say: Say,
    ) -> None:
        self.inputs = list(inputs)
        self.bad = list(bad)
        self.out = out_dir
        self.s = settings
        self.client = client
        self.progress = progress
        self.say = say
        self.units: list[_Unit] = []
        self.map_specs: dict[str, tuple[Path, str]] = {}  # key -> (camera, view spec)
        self.map_futures: dict[str, Any] = {}
        self.costs: dict[str, float] = {
            k: 0.0
            for k in (
                "frames", "read_cpu_s", "remap_cpu_s", "write_cpu_s", "task_wall_s",
                "task_setup_s", "read_bytes", "segment_bytes", "join_s", "join_bytes",
                "range_tasks", "index_tasks", "join_tasks", "image_tasks", "images",
                "index_s", "reseeks",
            )
        }  # fmt: skip
        self.run_id = uuid.uuid4().hex[:8]
        self.bar: Any = None
        self._threads_at = 0.0
        self._threads = 1

    # ---- planning -------------------------------------------------------------------------

    def _plan(self, state: JournalState) -> None:
        root = common_root(self.inputs)
        collide = {
            b.name: b.reason
            for b in find_collisions(
                self.out, root, self.inputs, self.s.video_suffix, self.s.image_suffix
            )
        }
        for b in self.bad:
            self._fail(self._new_unit(None, b.name, "?"), b.reason)
        cameras: dict[Path, tuple[Any, str] | str] = {}
        options = dict(self.s.camera_options)
        for item in self.inputs:
            u = self._new_unit(item, str(item.path), item.kind)
            if str(item.path) in collide:
                self._fail(u, collide[str(item.path)])
                continue
            cam = cameras.get(item.camera)
            if cam is None:
                try:
                    cam = (load_camera(item.camera, options), file_hash(item.camera))
                except OmnidevError as exc:
                    cam = f"calibration {item.camera}: {_one_line(str(exc))}"
                cameras[item.camera] = cam
            if isinstance(cam, str):
                self._fail(u, cam)
                continue
            camera, cam_hash = cam
            u.camera_size = tuple(camera.image_size)  # type: ignore[assignment]
            view_fields = [(v.name, v.spec) for v in item.views]
            u.key = unit_key(item.path, cam_hash, {**self.s.output_fields(), "views": view_fields})
            u.outputs = [
                output_path(self.out, root, item, v, self.s.video_suffix, self.s.image_suffix)
                for v in item.views
            ]
            for v in item.views:
                mk = f"{cam_hash[:16]}-{_spec_key(v.spec)}"
                self.map_specs.setdefault(mk, (item.camera, v.spec))
                u.map_keys.append(mk)
            done = state.unit_done(u.key)
            if done is not None:
                u.report.status = "skipped"
                u.report.frames = int(done.get("frames", 0))
                u.report.ranges = u.report.ranges_before = int(done.get("ranges", 0))
                u.report.outputs = [str(p) for p in u.outputs]
                continue
            started = u.key in state.index or u.key in state.ranges
            if not self.s.force and not started:
                exists = [p for p in u.outputs if p.exists()]
                if exists:
                    self._fail(u, f"{exists[0]} exists; pass --force to overwrite it")
                    continue
            if item.kind == "video" and u.key in state.index:
                u.index = _index_from_record(state.index[u.key]["index"])
                self._ranges_from_index(u, state)

    def _new_unit(self, item: BatchInput | None, name: str, kind: str) -> _Unit:
        u = _Unit(item, UnitReport(name, kind))
        self.units.append(u)
        return u

    def _ranges_from_index(self, u: _Unit, state: JournalState | None) -> None:
        assert u.index is not None
        u.report.frames = u.index.frames
        u.report.ranges = len(u.index.ranges)
        for r in u.index.ranges:
            rec = state.range_done(u.key, r.number) if state is not None else None
            if rec is not None:
                u.done[r.number] = rec
            else:
                u.todo.add(r.number)
        u.report.ranges_before = len(u.done)

    # ---- running --------------------------------------------------------------------------

    def run(self) -> JobReport:
        t0 = time.perf_counter()
        self.out.mkdir(parents=True, exist_ok=True)
        interrupted = False
        with Journal(self.out) as journal:
            self.journal = journal
            self._plan(journal.load())
            queue = self._initial_work()
            total = sum(
                (u.index.frames if u.index else 0) if u.report.kind == "video" else 1
                for u in self.units
                if u.report.status == "pending"
            )
            done_before = sum(
                sum(int(rec["frames"]) for rec in u.done.values())
                for u in self.units
                if u.report.status == "pending"
            )
            self.bar = tqdm(
                total=total, initial=done_before, unit="frame", file=sys.stderr,
                disable=not self.progress or not queue, dynamic_ncols=True, leave=False,
            )  # fmt: skip
            try:
                self._loop(queue)
            except KeyboardInterrupt:
                interrupted = True
            finally:
                self.bar.close()
        for u in self.units:
            if u.report.status == "pending" and not interrupted:
                self._fail(u, "not finished (internal error: no task left for it)")
        report = JobReport(
            [u.report for u in self.units],
            time.perf_counter() - t0,
            *self._workers(),
            len(self.map_futures),
            self.costs,
            interrupted,
        )
        if interrupted:
            exc = KeyboardInterrupt()
            exc.report = report  # type: ignore[attr-defined]
            raise exc
        return report

    def _workers(self) -> tuple[int, int]:
        try:
            nthreads = self.client.nthreads()
        except Exception:  # a client that lost its scheduler at the end
            return 0, 0
        return len(nthreads), int(sum(nthreads.values()))

    def _initial_work(self) -> deque[_Work]:
        queue: deque[_Work] = deque()
        images: dict[tuple[str, ...], list[int]] = {}
        for i, u in enumerate(self.units):
            if u.report.status != "pending":
                continue
            assert u.item is not None
            u.t0 = time.perf_counter()
            if u.item.kind == "image":
                images.setdefault(tuple(u.map_keys), []).append(i)
            elif u.index is None:
                queue.append(_Work("index", (i,)))
            else:
                queue.extend(self._range_work(i))
        for group in images.values():
            n = max(1, self.s.images_per_task)
            for k in range(0, len(group), n):
                queue.append(_Work("images", tuple(group[k : k + n])))
        return queue

    def _range_work(self, i: int) -> list[_Work]:
        u = self.units[i]
        assert u.index is not None
        if not u.todo:
            return [_Work("join", (i,))]
        return [_Work("range", (i,), u.index.ranges[n]) for n in sorted(u.todo)]

    def _window(self) -> int:
        now = time.monotonic()
        if now - self._threads_at > 2.0:
            self._threads = max(1, self._workers()[1])
            self._threads_at = now
        return max(4, 2 * self._threads + 2)

    def _loop(self, queue: deque[_Work]) -> None:
        from distributed import as_completed

        inflight: dict[Any, _Work] = {}
        ac = as_completed()  # type: ignore[no-untyped-call]
        try:
            while queue or inflight:
                while queue and len(inflight) < self._window():
                    work = queue.popleft()
                    if any(self.units[i].failed for i in work.units) and work.kind != "images":
                        continue
                    fut = self._submit(work)
                    inflight[fut] = work
                    ac.add(fut)  # type: ignore[no-untyped-call]
                if not inflight:
                    continue
                fut = next(ac)
                work = inflight.pop(fut)
                follow = self._finished(fut, work)
                # joins first (they free disk space), then what the result opened up
                for w in follow:
                    if w.kind == "join":
                        queue.appendleft(w)
                    else:
                        queue.append(w)
        except BaseException:
            for f in inflight:
                with contextlib.suppress(Exception):
                    f.cancel()
            raise

    def _maps(self, keys: Sequence[str]) -> list[Any]:
        out = []
        for k in keys:
            fut = self.map_futures.get(k)
            if fut is None:
                camera, spec = self.map_specs[k]
                fut = self.client.submit(
                    _build_maps_task,
                    str(camera),
                    tuple(self.s.camera_options),
                    spec,
                    key=f"omnidev-maps-{k}-{self.run_id}",
                )
                self.map_futures[k] = fut
            out.append(fut)
        return out

    def _submit(self, w: _Work) -> Any:
        u = self.units[w.units[0]]
        tag = f"{u.key or 'x'}-{self.run_id}-{uuid.uuid4().hex[:6]}"
        if w.kind == "index":
            assert u.item is not None
            return self.client.submit(
                tasks.index_task, str(u.item.path), u.camera_size, self.s.range_frames,
                key=f"omnidev-index-{tag}",
            )  # fmt: skip
        if w.kind == "range":
            assert u.item is not None and u.index is not None and w.frames is not None
            return self.client.submit(
                tasks.range_task, self._range_job(u, w.frames), self._maps(u.map_keys),
                key=f"omnidev-range-{tag}",
            )  # fmt: skip
        if w.kind == "join":
            return self.client.submit(_join_all, self._join_jobs(u), key=f"omnidev-join-{tag}")
        job = tasks.ImagesJob(
            tuple(str(self.units[i].item.path) for i in w.units),  # type: ignore[union-attr]
            tuple(tuple(str(p) for p in self.units[i].outputs) for i in w.units),
            self.s.interpolation,
            tuple(u.map_keys),
            self.s.task_threads,
        )
        return self.client.submit(
            tasks.images_task, job, self._maps(u.map_keys), key=f"omnidev-images-{tag}"
        )

    def _segment(self, u: _Unit, view: int, number: int) -> Path:
        assert u.item is not None
        name = u.item.views[view].name
        return self.journal.unit_segments(u.key) / name / f"{number:06d}{self.s.video_suffix}"

    def _fps(self, u: _Unit) -> float:
        assert u.index is not None
        return self.s.fps or u.index.fps or 25.0

    def _range_job(self, u: _Unit, r: FrameRange) -> tasks.RangeJob:
        from omnidev.cli.unwarp_cmd import frame_layout, output_layouts

        assert u.index is not None and u.item is not None
        views = [parse_view(v.spec) for v in u.item.views]
        even = all(v.width % 2 == 0 and v.height % 2 == 0 for v in views)
        layout = frame_layout(u.index.native_layout, []) if even else "bgr"
        return tasks.RangeJob(
            path=str(u.item.path),
            frames=r,
            layout=layout,
            out_layouts=output_layouts(layout),
            interpolation=self.s.interpolation,
            fps=self._fps(u),
            segments=tuple(str(self._segment(u, v, r.number)) for v in range(len(u.outputs))),
            encode=self.s.encode,
            map_keys=tuple(u.map_keys),
            threads=self.s.task_threads,
        )

    def _join_jobs(self, u: _Unit) -> list[tasks.JoinJob]:
        assert u.index is not None
        jobs = []
        for v, target in enumerate(u.outputs):
            segs = tuple(
                (str(self._segment(u, v, r.number)), r.start, r.frames) for r in u.index.ranges
            )
            jobs.append(tasks.JoinJob(segs, str(target), self._fps(u)))
        return jobs

    # ---- results --------------------------------------------------------------------------

    def _fail(self, u: _Unit, message: str) -> None:
        if u.failed:
            return
        message = _one_line(message)
        u.report.status = "failed"
        u.report.error = message
        name = u.report.input
        self.say(message if name in message else f"{name}: {message}")
        if u.key:
            self.journal.record({"kind": "failed", "unit": u.key, "input": name, "error": message})

    def _finished(self, fut: Any, w: _Work) -> list[_Work]:
        from distributed.scheduler import KilledWorker

        if fut.status != "finished":
            exc = None
            with contextlib.suppress(Exception):
                exc = fut.exception()
            if isinstance(exc, KilledWorker):
                why = (
                    f"its {w.kind} task was lost with its worker too often (the worker crashed "
                    "or ran out of memory)"
                )
            elif exc is None:
                why = f"its {w.kind} task was cancelled"
            else:
                why = f"internal error in its {w.kind} task: {type(exc).__name__}: {exc}"
            for i in w.units:
                self._fail(self.units[i], why)
            return []
        result = fut.result()
        i = w.units[0]
        u = self.units[i]
        if isinstance(result, tasks.Failure):
            for j in w.units:
                self._fail(self.units[j], result.message)
            return []
        if w.kind == "index":
            assert isinstance(result, VideoIndex)
            self.costs["index_tasks"] += 1
            u.index = result
            self.journal.record(
                {"kind": "index", "unit": u.key, "input": u.report.input,
                 "index": _index_record(result)}
            )  # fmt: skip
            self._ranges_from_index(u, None)
            self.bar.total += result.frames
            self.bar.refresh()
            return self._range_work(i)
        if w.kind == "range":
            assert isinstance(result, tasks.RangeResult) and w.frames is not None
            r = w.frames
            segments = [
                {"path": str(self._segment(u, v, r.number)), "bytes": b}
                for v, b in enumerate(result.segment_bytes)
            ]
            self.journal.record(
                {"kind": "range", "unit": u.key, "range": r.number, "frames": result.frames,
                 "segments": segments, "worker": result.worker}
            )  # fmt: skip
            u.done[r.number] = {"frames": result.frames}
            u.todo.discard(r.number)
            u.report.ranges_run += 1
            self._add_costs(result)
            self.bar.update(result.frames)
            return [_Work("join", (i,))] if not u.todo else []
        if w.kind == "join":
            joined: list[tasks.JoinResult] = result
            frames = {j.frames for j in joined}
            if frames != {u.report.frames}:
                self._fail(u, f"joined {sorted(frames)} frames, expected {u.report.frames}")
                return []
            self.costs["join_tasks"] += 1
            self.costs["join_s"] += sum(j.wall_s for j in joined)
            self.costs["join_bytes"] += sum(j.bytes for j in joined)
            self._complete(u, ranges=len(u.index.ranges) if u.index else 0)
            if not self.s.keep_segments:
                shutil.rmtree(self.journal.unit_segments(u.key), ignore_errors=True)
            return []
        assert isinstance(result, tasks.ImagesResult)
        self.costs["image_tasks"] += 1
        for k, (j, err) in enumerate(zip(w.units, result.errors, strict=True)):
            if err is not None:
                self._fail(self.units[j], err)
            else:
                self.units[j].report.frames = 1
                self._complete(self.units[j], ranges=0)
            self.bar.update(1)
            del k
        self.costs["images"] += sum(e is None for e in result.errors)
        for stage, v in result.cpu_s.items():
            self.costs[f"{stage}_cpu_s"] += v
        return []

    def _complete(self, u: _Unit, *, ranges: int) -> None:
        u.report.status = "ok"
        u.report.outputs = [str(p) for p in u.outputs]
        u.report.seconds = round(time.perf_counter() - u.t0, 3)
        self.journal.record(
            {"kind": "done", "unit": u.key, "input": u.report.input, "frames": u.report.frames,
             "ranges": ranges, "outputs": u.report.outputs}
        )  # fmt: skip

    def _add_costs(self, r: tasks.RangeResult) -> None:
        c = self.costs
        c["range_tasks"] += 1
        c["frames"] += r.frames
        c["task_wall_s"] += r.wall_s
        c["task_setup_s"] += r.setup_s
        c["read_bytes"] += r.read_bytes
        c["segment_bytes"] += sum(r.segment_bytes)
        c["reseeks"] += r.reseeks
        for stage, v in r.cpu_s.items():
            c[f"{stage}_cpu_s"] += v


def _spec_key(spec: str) -> str:
    import hashlib

    return hashlib.sha256(spec.encode()).hexdigest()[:12]


def _build_maps_task(
    camera: str, options: tuple[tuple[str, str], ...], spec: str
) -> Maps | tasks.Failure:
    """Load a calibration and build one view's maps (runs once per camera and view)."""
    try:
        cam = load_camera(Path(camera), dict(options))
        return build_maps(cam, parse_view(spec))
    except OmnidevError as exc:
        return tasks.Failure(f"calibration {camera}: {exc}")
    except ValueError as exc:  # a view the camera cannot fill
        return tasks.Failure(f"calibration {camera}, view {spec}: {exc}")


def _join_all(jobs: Sequence[tasks.JoinJob]) -> list[tasks.JoinResult] | tasks.Failure:
    out = []
    for j in jobs:
        r = tasks.join_task(j)
        if isinstance(r, tasks.Failure):
            return r
        out.append(r)
    return out


def _index_record(ix: VideoIndex) -> dict[str, Any]:
    d = asdict(ix)
    d["ranges"] = [[r.number, r.start, r.stop, r.start_pts, r.stop_pts] for r in ix.ranges]
    return d


def _index_from_record(d: dict[str, Any]) -> VideoIndex:
    ranges = tuple(FrameRange(*r) for r in d["ranges"])
    return VideoIndex(
        frames=int(d["frames"]),
        size=(int(d["size"][0]), int(d["size"][1])),
        fps=d["fps"],
        native_layout=str(d["native_layout"]),
        keyframes=int(d["keyframes"]),
        ranges=ranges,
        bytes=int(d["bytes"]),
        split=str(d.get("split", "")),
    )


def start_local_cluster(workers: int, threads_per_worker: int = 1) -> tuple[Any, Any]:
    """A Dask cluster of ``workers`` processes on this machine and a client to it.

    The workers do not run Dask's statistical profiler (a thread sampling every
    worker thread's stack every 10 ms, for the dashboard, which this cluster
    does not serve): it cost 2-5 % of a batch job's time here (docs/batch.md).
    """
    import logging

    import dask
    from distributed import Client, LocalCluster

    with dask.config.set({"distributed.worker.profile.enabled": False}):
        cluster = LocalCluster(  # type: ignore[no-untyped-call]
            n_workers=workers,
            threads_per_worker=threads_per_worker,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        )
    return cluster, Client(cluster)  # type: ignore[no-untyped-call]


def connect(address: str | None, timeout_s: float = 30.0) -> Any:
    """A client of the scheduler at ``address`` (None: the Dask config's ``scheduler-address``)."""
    from distributed import Client

    try:
        if address:
            return Client(address, timeout=timeout_s)  # type: ignore[no-untyped-call]
        return Client(timeout=timeout_s)  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError) as exc:
        where = address or "the Dask config's scheduler-address"
        raise OmnidevError(f"cannot reach the Dask scheduler at {where}: {exc}") from None


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1
