"""``omnidev batch unwarp`` on a real Dask cluster: frame-exact, resumable, fault tolerant.

A scheduler and two worker processes (``dask scheduler`` / ``dask worker``,
one thread each, no nanny) are started on localhost, and the command reaches
them with ``--scheduler``. The fixture batch holds three rendered fisheye
clips in three GOP structures (H.264 closed GOP with B-frames in MP4, H.264
open GOP with scene cuts in MKV, all-intra Motion JPEG in AVI), each frame
turned a further step so that every frame differs, two images, and three bad
inputs (a missing file, a corrupt video, a video of the wrong size). Every
output is compared, decoded frame by frame, with single-process
``omnidev unwarp`` of the same input: the encoders are deterministic per frame
(Motion JPEG) or lossless (x264 crf=0), so the decoded frames must be
identical, not merely close.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from omnidev.batch.avrange import index_video, plan_ranges
from omnidev.batch.inputs import collect_inputs, name_views
from omnidev.batch.journal import STATE_DIR
from omnidev.cli.main import main
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.camfile import write_camera_file
from omnidev.fisheye.models import IdealFisheye
from omnidev.sim.fisheye import EquidistantFisheyeCamera
from omnidev.sim.render import render_omni
from omnidev.sim.scene import RoomScene

av = pytest.importorskip("av", reason="PyAV decodes and joins the video ranges")
pytest.importorskip("distributed", reason="omnidev batch needs dask[distributed] (extra 'batch')")

SIZE = 192
FRAMES = 48
VIEWS = ["panorama:192x48", "front=perspective:64x48,fov=90,tilt=-30"]
# (file, x264/encoder options): three GOP structures
CLIPS = {
    "a.mp4": ("libx264", {"g": "12", "bf": "2", "x264-params": "scenecut=0:open-gop=0"}),
    "sub/b.mkv": ("libx264", {"g": "10", "bf": "3", "x264-params": "open-gop=1"}),
    "c.avi": ("mjpeg", {}),
}


def _camera(tmp: Path, size: int) -> Path:
    f = 0.5 * size / math.radians(95)
    c = (size - 1) / 2
    cam = tmp / f"fisheye{size}.yml"
    lens = IdealFisheye("equidistant", f, c, c)
    write_camera_file(cam, FisheyeCamera(lens, (size, size), MOUNTS["up"], max_angle_deg=95.0))
    return cam


def _render(size: int, seed: int) -> np.ndarray:
    f = 0.5 * size / math.radians(95)
    c = (size - 1) / 2
    sim = EquidistantFisheyeCamera(f, (size, size), (c, c), math.radians(95))
    return render_omni(sim, RoomScene(seed=seed), supersample=1)


def _write_clip(path: Path, base: np.ndarray, codec: str, options: dict[str, str]) -> None:
    size = base.shape[0]
    c = (size - 1) / 2
    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), "w") as out:
        stream = out.add_stream(codec, rate=25)
        stream.width = stream.height = size
        stream.pix_fmt = "yuvj420p" if codec == "mjpeg" else "yuv420p"
        stream.options = options
        for i in range(FRAMES):
            turn = cv2.getRotationMatrix2D((c, c), 360.0 * i / FRAMES, 1.0)
            image = cv2.warpAffine(base, turn, (size, size))
            frame = av.VideoFrame.from_ndarray(image, format="bgr24")
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)


@pytest.fixture(scope="module")
def batch(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp("batch")
    src = tmp / "in"
    src.mkdir()
    cam = _camera(tmp, SIZE)
    for seed, (name, (codec, opts)) in enumerate(CLIPS.items(), start=3):
        _write_clip(src / name, _render(SIZE, seed), codec, opts)
    for k in range(2):
        cv2.imwrite(str(src / f"img{k}.png"), _render(SIZE, 20 + k))
    # bad inputs: a missing file, a corrupt video, a video of another size
    corrupt = src / "corrupt.mp4"
    corrupt.write_bytes(np.random.default_rng(5).integers(0, 256, 20000, np.uint8).tobytes())
    _write_clip(src / "small.mp4", _render(128, 9), "libx264", {"g": "12"})
    return {"tmp": tmp, "src": src, "cam": cam}


def _single(batch: dict[str, Any], name: str, suffix: str, encode: str) -> list[tuple[str, Path]]:
    """Single-process ``omnidev unwarp`` of one input into every view (cached)."""
    ref = batch["tmp"] / f"single{suffix}{encode.replace('?', '-')}"
    outs = []
    argv = ["unwarp", str(batch["src"] / name), "--camera", str(batch["cam"]), "--threads", "1"]
    for view in name_views(VIEWS, "VIEWS"):
        out = ref / view.name / Path(name).with_suffix(suffix)
        out.parent.mkdir(parents=True, exist_ok=True)
        argv += ["--view", view.spec, "-o", f"file:{out}{encode}"]
        outs.append((view.name, out))
    if not all(o.exists() for _, o in outs):
        assert main(argv) == 0
    return outs


def _decoded(path: Path) -> list[np.ndarray]:
    if path.suffix == ".png":
        return [cv2.imread(str(path), cv2.IMREAD_UNCHANGED)]
    with av.open(str(path)) as c:
        return [f.to_ndarray(format="yuv420p") for f in c.decode(video=0)]


def _assert_identical(
    batch: dict[str, Any], out: Path, suffix: str, encode: str, videos: bool = False
) -> int:
    """Every output of ``out`` decodes to the single-process frames; returns frames compared."""
    n = 0
    for name in [*CLIPS] + ([] if videos else ["img0.png", "img1.png"]):
        sfx = ".png" if name.endswith(".png") else suffix
        for view, ref in _single(batch, name, sfx, "" if sfx == ".png" else encode):
            got = out / view / Path(name).with_suffix(sfx)
            a, b = _decoded(ref), _decoded(got)
            assert len(b) == len(a) == (1 if sfx == ".png" else FRAMES), (got, len(a), len(b))
            bad = [i for i, (x, y) in enumerate(zip(a, b, strict=True)) if not np.array_equal(x, y)]
            assert not bad, f"{got}: frames {bad[:5]} differ from omnidev unwarp's"
            n += len(a)
    return n


def _dask(*args: str) -> subprocess.Popen[bytes]:
    exe = Path(sys.executable).with_name("dask")
    return subprocess.Popen([str(exe), *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


class Cluster:
    """A scheduler and worker processes on localhost, started as a user would."""

    def __init__(self, tmp: Path, workers: int) -> None:
        self.file = tmp / f"scheduler-{time.monotonic_ns()}.json"
        self.procs = [
            _dask("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                  "--scheduler-file", str(self.file))
        ]  # fmt: skip
        self.address = self._scheduler_address(deadline=time.monotonic() + 60)
        self.workers = [
            _dask("worker", "--scheduler-file", str(self.file), "--nthreads", "1", "--no-nanny",
                  "--no-dashboard", "--host", "127.0.0.1")
            for _ in range(workers)
        ]  # fmt: skip
        self.procs += self.workers
        from distributed import Client

        with Client(self.address, timeout=30) as client:
            client.wait_for_workers(workers, timeout=60)
            pids = client.run(os.getpid)
        self.address_of = {pid: addr for addr, pid in pids.items()}  # worker pid -> address

    def _scheduler_address(self, deadline: float) -> str:
        """The address in the scheduler file, once dask has finished writing it (not atomic)."""
        while time.monotonic() < deadline:
            try:
                return str(json.loads(self.file.read_text())["address"])
            except (FileNotFoundError, json.JSONDecodeError, KeyError):
                time.sleep(0.1)
        raise AssertionError(f"dask scheduler did not write {self.file} within 60 s")

    def close(self) -> None:
        for p in reversed(self.procs):
            if p.poll() is None:
                p.terminate()
        for p in self.procs:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


@pytest.fixture(scope="module")
def cluster(batch: dict[str, Any]) -> Iterator[Cluster]:
    c = Cluster(batch["tmp"], 2)
    yield c
    c.close()


def _argv(batch: dict[str, Any], out: Path, *extra: str, videos: bool = False) -> list[str]:
    """The batch command; ``videos``: only the three good clips."""
    src = batch["src"]
    inputs = [src / "*.mp4", src / "sub" / "b.mkv", src / "c.avi", src / "img*.png"]
    if videos:
        inputs = [src / name for name in CLIPS]
    argv = ["batch", "unwarp", *map(str, inputs)]
    argv += [] if videos else [str(src / "missing.mp4")]
    argv += ["--camera", str(batch["cam"]), "--out", str(out), "--range-frames", "12"]
    argv += ["--images-per-task", "1", "--no-progress", "--json"]
    for v in VIEWS:
        argv += ["--view", v]
    return argv + list(extra)


def _report(captured: str) -> dict[str, Any]:
    line = [s for s in captured.splitlines() if s.startswith("{")][-1]
    return dict(json.loads(line))


def test_batch_is_frame_exact_and_reports_bad_inputs(batch, cluster, capsys):
    out = batch["tmp"] / "out-avi"
    rc = main(_argv(batch, out, "--scheduler", cluster.address, "--format", "avi"))
    cap = capsys.readouterr()
    report = _report(cap.out)
    assert rc == 1, cap.err  # some inputs failed, the others finished
    status = {Path(u["input"]).name: u["status"] for u in report["inputs"]}
    assert status == {
        "a.mp4": "ok", "b.mkv": "ok", "c.avi": "ok", "img0.png": "ok", "img1.png": "ok",
        "missing.mp4": "failed", "corrupt.mp4": "failed", "small.mp4": "failed",
    }  # fmt: skip
    # each bad input: exactly one line on stderr, naming it and saying what is wrong
    lines = [s for s in cap.err.splitlines() if s.strip()]
    for name, why in (
        ("missing.mp4", "not found"),
        ("corrupt.mp4", "cannot read"),
        ("small.mp4", "128x128; the calibration is for 192x192"),
    ):
        hits = [s for s in lines if name in s]
        assert len(hits) == 1 and why in hits[0], (name, lines)
    assert "Traceback" not in cap.err
    # ranges start at keyframes: 48 frames at GOP 12 -> 4 ranges, GOP 10 -> 4 (12 each or more)
    ranges = {Path(u["input"]).name: u["ranges"] for u in report["inputs"] if u["kind"] == "video"}
    assert ranges["a.mp4"] == 4 and ranges["c.avi"] == 4 and 2 <= ranges["b.mkv"] <= 4
    assert report["maps_built"] == len(VIEWS)  # once per camera and view, not per task
    assert report["workers"] == 2
    n = _assert_identical(batch, out, ".avi", "")
    assert n == 3 * FRAMES * len(VIEWS) + 2 * len(VIEWS)
    assert not any((out / STATE_DIR / "segments").iterdir())  # joined segments are removed


def _journal_ranges(out: Path) -> list[dict[str, Any]]:
    path = out / STATE_DIR / "journal.jsonl"
    if not path.exists():
        return []
    recs = []
    for line in path.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if rec.get("kind") == "range":
            recs.append(rec)
    return recs


def _wait_for(cond: Any, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < deadline, "timed out waiting for the batch job"
        time.sleep(0.02)


def test_interrupted_job_reruns_only_missing_ranges(batch, cluster, capsys):
    out = batch["tmp"] / "out-resume"
    argv = _argv(
        batch, out, "--scheduler", cluster.address, "--format", "mp4", "--encode", "crf=0",
        videos=True,
    )  # fmt: skip
    cmd = [sys.executable, "-m", "omnidev.cli.main", *argv]
    for _attempt in range(3):
        job = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            # the first finished range: later, on a quiet machine the job could finish the
            # remaining ranges (0.1-0.2 s each here) before the signal lands
            _wait_for(lambda: len(_journal_ranges(out)) >= 1, timeout_s=120.0)
            job.send_signal(signal.SIGINT)
            _, err = job.communicate(timeout=60)
        finally:
            if job.poll() is None:
                job.kill()
        if job.returncode != 0:
            break
        shutil.rmtree(out)  # the whole job beat the signal: a race of the test, try again
    assert job.returncode == 130, err
    assert "run the same command to finish" in err
    before = {(r["unit"], r["range"]) for r in _journal_ranges(out)}
    capsys.readouterr()
    assert main(argv) == 0  # the same command again, here in-process
    report = _report(capsys.readouterr().out)
    videos = [u for u in report["inputs"] if u["kind"] == "video" and u["status"] != "failed"]
    total = sum(u["ranges"] for u in videos)
    run_now = sum(u["ranges_run"] for u in videos)
    had = sum(u["ranges_before"] for u in videos)
    assert 1 <= len(before) < total and had == len(before)
    assert run_now == total - had  # only the missing ranges ran
    after = _journal_ranges(out)
    again = [(r["unit"], r["range"]) for r in after if (r["unit"], r["range"]) in before]
    assert len(again) == len(before)  # no range finished before was run again
    _assert_identical(batch, out, ".mp4", "?crf=0", videos=True)


def test_plan_ranges_at_keyframes_of_a_real_file(batch):
    ix = index_video(batch["src"] / "a.mp4", 12)
    assert ix.frames == FRAMES and ix.keyframes == FRAMES // 12
    assert [(r.start, r.stop) for r in ix.ranges] == [(0, 12), (12, 24), (24, 36), (36, 48)]
    # round(30 / 10) = 3 ranges, each cut at the keyframe nearest to its third
    assert [(r.start, r.stop) for r in plan_ranges(range(30), [0, 7, 14, 21, 28], 10)] == [
        (0, 7),
        (7, 21),
        (21, 30),
    ]
    # as equal as the keyframes allow: 240 + 240, not 288 + 192 ("250 or more")
    ranges = plan_ranges(range(480), range(0, 480, 48), 250)
    assert [(r.start, r.stop) for r in ranges] == [(0, 240), (240, 480)]
    # sparse keyframes give fewer ranges; none after the first frame, one range
    assert len(plan_ranges(range(1000), [0, 900], 250)) == 2
    assert [(r.start, r.stop) for r in plan_ranges(range(1000), [0], 250)] == [(0, 1000)]


def test_bad_command_is_one_line(batch, capsys, tmp_path):
    rc = main(["batch", "unwarp", str(batch["src"] / "a.mp4"), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "--camera" in err
    shutil.rmtree(tmp_path, ignore_errors=True)
    os.makedirs(tmp_path, exist_ok=True)


def test_local_cluster_is_frame_exact_and_shut_down(batch):
    """Without --scheduler the command starts its own LocalCluster (2 worker processes)."""
    import psutil

    out = batch["tmp"] / "out-local"
    src = batch["src"]
    clips = _argv(batch, out, "--workers", "2", "--format", "avi", videos=True)
    argv = [*clips[:5], str(src / "img0.png"), str(src / "img1.png"), *clips[5:]]  # + images
    cmd = [sys.executable, "-m", "omnidev.cli.main", *argv]
    job = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    me = psutil.Process(job.pid)
    seen: set[int] = set()
    try:
        while job.poll() is None:  # every process the command starts, while it runs
            with contextlib.suppress(psutil.Error):
                seen |= {c.pid for c in me.children(recursive=True)}
            time.sleep(0.05)
        stdout, err = job.communicate(timeout=60)
    finally:
        if job.poll() is None:
            job.kill()
    assert job.returncode == 0, err
    report = _report(stdout)
    assert report["workers"] == 2 and report["threads"] == 2
    assert {u["status"] for u in report["inputs"]} == {"ok"} and len(report["inputs"]) == 5
    assert len(seen) >= 2  # the two workers (and their nanny's helpers) were seen
    # the cluster is shut down with the command: none of its processes outlives it
    _wait_for(lambda: not any(_alive(pid) for pid in seen), timeout_s=10.0)
    assert _assert_identical(batch, out, ".avi", "") == 3 * FRAMES * len(VIEWS) + 2 * len(VIEWS)


def _alive(pid: int) -> bool:
    import psutil

    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_manifests_parse_to_their_inputs(tmp_path):
    """CSV and JSON lines: paths and globs relative to the manifest, a row's own camera and
    views or the command's, view names, the row each input came from."""
    for name in ("cam1.yml", "cam2.yml", "v1.mp4", "sub/v2.mp4", "sub/v3.mkv", "img.png"):
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_bytes(b"x")
    (tmp_path / "m.csv").write_text(
        "Input , Camera,views\n"
        'sub/*,cam2.yml,"front=perspective:64x48,fov=90;panorama:64x16"\n'
        "\n"
        "v1.mp4\n",
        encoding="utf-8",
    )
    (tmp_path / "m.jsonl").write_text(
        "# one input per line\n"
        '{"input": "img.png", "camera": "cam2.yml", "views": "a=panorama:32x8;b=panorama:64x16"}\n'
        "\n"
        '{"input": "sub/v2.mp4", "views": ["plane:32x24,d=1,w=1,z=-1:0"]}\n',
        encoding="utf-8",
    )
    good, bad = collect_inputs(
        ["m.csv", "m.jsonl"], camera=Path("cam1.yml"), views=["panorama:128x32"], cwd=tmp_path
    )
    assert bad == []
    got = [
        (g.path.relative_to(tmp_path).as_posix(), g.camera.name,
         [(v.name, v.spec) for v in g.views], g.origin, g.kind)
        for g in good
    ]  # fmt: skip
    two = [("front", "perspective:64x48,fov=90"), ("panorama", "panorama:64x16")]
    assert got == [
        ("sub/v2.mp4", "cam2.yml", two, "m.csv row 1", "video"),
        ("sub/v3.mkv", "cam2.yml", two, "m.csv row 1", "video"),
        ("v1.mp4", "cam1.yml", [("panorama", "panorama:128x32")], "m.csv row 3", "video"),
        ("img.png", "cam2.yml", [("a", "panorama:32x8"), ("b", "panorama:64x16")],
         "m.jsonl line 2", "image"),
        # sub/v2.mp4 again (line 4): named twice, it runs once, with its first views
    ]  # fmt: skip


def test_bad_manifest_rows_each_get_one_line(batch, cluster, capsys, tmp_path):
    """Each bad row: one stderr line naming the manifest and row; the good rows finish."""
    src, cam = batch["src"], batch["cam"]
    (tmp_path / "m.csv").write_bytes(
        b"input,camera,views\n"
        + f"{src / 'a.mp4'},{cam},panorama:192x48\n".encode()  # row 1: good
        + f",{cam},panorama:192x48\n".encode()  # 2: no input
        + f"{src / 'a.mp4'},{cam},bogus:1x1\n".encode()  # 3: unknown view
        + f"{src / 'missing.mp4'},{cam},panorama:192x48\n".encode()  # 4: no such file
        + f"{src / 'a.mp4'},{cam},plane:32x24,w=1\n".encode()  # 5: unquoted comma
        + b"\xff\xfe.mp4,x.yml,panorama:192x48\n"  # 6: not UTF-8
        + f"{src / 'c.avi'},,\n".encode()  # 7: no camera (the command gives none)
    )
    (tmp_path / "m.jsonl").write_bytes(
        json.dumps({"input": str(src / "c.avi"), "camera": str(cam), "views": ["panorama:192x48"]})
        .encode() + b"\n"  # line 1: good
        + b'{"input": "x.mp4",\n'  # 2: bad JSON
        + b"[1, 2]\n"  # 3: not an object
        + json.dumps({"input": str(src / "c.avi"), "camara": str(cam)}).encode() + b"\n"  # 4
        + b'{"input": "\xe9.mp4"}\n'  # 5: not UTF-8 (Latin-1)
    )  # fmt: skip
    out = tmp_path / "out"
    argv = ["batch", "unwarp", str(tmp_path / "m.csv"), str(tmp_path / "m.jsonl"),
            "--out", str(out), "--scheduler", cluster.address, "--format", "avi",
            "--no-progress", "--json"]  # fmt: skip
    rc = main(argv)
    cap = capsys.readouterr()
    assert rc == 1 and "Traceback" not in cap.err, cap.err
    report = _report(cap.out)
    ok = sorted(Path(u["input"]).name for u in report["inputs"] if u["status"] == "ok")
    assert ok == ["a.mp4", "c.avi"] and report["failed"] == 10
    lines = [s for s in cap.err.splitlines() if s.strip()]
    assert len(lines) == 10, lines
    for where, why in (
        ("m.csv row 2", "no input"),
        ("m.csv row 3", "bogus"),
        ("m.csv row 4", "file not found"),
        ("m.csv row 5", "4 fields, the header has 3"),
        ("m.csv row 6", "not UTF-8"),
        ("m.csv row 7", "no camera"),
        ("m.jsonl line 2", "not JSON"),
        ("m.jsonl line 3", "not a JSON object"),
        ("m.jsonl line 4", "unknown key 'camara'"),
        ("m.jsonl line 5", "not UTF-8"),
    ):
        hits = [s for s in lines if where in s]
        assert len(hits) == 1 and why in hits[0], (where, lines)
    assert (out / "panorama" / "a.avi").is_file() and (out / "panorama" / "c.avi").is_file()


@pytest.mark.parametrize(
    ("name", "content", "why"),
    [
        ("m.csv", None, "file not found"),
        ("m.csv", b"", "no rows"),
        ("m.csv", b"input,camera,views\n\n", "no rows"),
        ("m.jsonl", b"# nothing yet\n\n", "no rows"),
        ("m.csv", b"path,camera\na.mp4,c.yml\n", "must name an 'input' column"),
        ("m.csv", b"input,camara\na.mp4,c.yml\n", "unknown column 'camara'"),
        ("m.csv", b"input,views,views\na.mp4,,\n", "two 'views' columns"),
        ("m.csv", b"input,\xff\n", "header is not UTF-8"),
    ],
)
def test_unusable_manifest_is_one_line(tmp_path, capsys, name, content, why):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    rc = main(["batch", "unwarp", str(path), "--out", str(tmp_path / "out"), "--workers", "1"])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and str(path) in err and why in err, err
    assert not (tmp_path / "out").exists()  # stopped before any cluster or output


def test_killed_worker_job_completes_identically(batch, cluster):
    """Last in the file: it kills one of the module's two workers."""
    out = batch["tmp"] / "out-kill"
    argv = _argv(batch, out, "--scheduler", cluster.address, "--format", "avi", videos=True)
    result: dict[str, Any] = {}

    def run() -> None:
        result["rc"] = main(argv)

    t = threading.Thread(target=run)
    t.start()
    _wait_for(lambda: len(_journal_ranges(out)) >= 1 or not t.is_alive())
    victim = cluster.workers[0]
    victim.send_signal(signal.SIGKILL)
    victim.wait(10)
    killed_at = len(_journal_ranges(out))
    t.join(120)
    assert not t.is_alive()
    assert result["rc"] == 0
    recs = _journal_ranges(out)
    survivor = cluster.address_of[cluster.workers[1].pid]
    assert {r["worker"] for r in recs} <= {cluster.address_of[victim.pid], survivor}
    # the job went on after the worker died, on the one left
    assert len(recs) > killed_at and recs[-1]["worker"] == survivor
    _assert_identical(batch, out, ".avi", "", videos=True)
