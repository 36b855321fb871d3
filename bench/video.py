"""File-to-file unwarping: ``omnidev unwarp`` against ffmpeg doing the same job in the same run.

Input (made once per run, or reused from $OMNIDEV_BENCH_CACHE): 300 frames (60 with
--quick) of 1920x1920 Motion JPEG (q 3, 4:2:0, as a 1920x1920 MJPEG camera sends):
omnidev.sim's room seen by an ideal 190-degree equidistant fisheye looking up,
turned 0.3 degrees further each frame, with sensor noise (sigma 2 levels).

Cases (each the whole command a user runs, timed from process start to exit, so
that loading the calibration and building the maps count; ``threads`` = the
usable cores for both; the same output codec and quality for both, once with
H.264 (libx264, preset veryfast, crf 20, .mp4: omnidev's default for .mp4) and
once with Motion JPEG (q 3, .avi: omnidev's default for .avi, keys ``*_mjpeg``),
4:2:0 as decoded):

- ``fisheye_equirect``: ``--view equirect:2048x512`` (the whole sphere) against
  ``v360=fisheye:equirect`` (ih_fov=iv_fov=190, pitch=-90, yaw=90, rorder=pyr: the
  same rays; the outputs agree to ``psnr_vs_ffmpeg_db`` where both see).
- ``fisheye_flat``: ``--view perspective:1280x720,fov=90,tilt=45`` against
  ``v360=fisheye:flat`` (h_fov 90, v_fov 58.72, the same direction).
- ``pano_table``: a pano-mapping table of a 1920x1920 hyperbolic-mirror camera
  (bench/unwarp.py's), ``--view panorama:2048x512`` with nearest-neighbour
  interpolation, against ffmpeg's ``remap`` filter fed omnidev's own maps as 16-bit
  PGM files (remap is nearest-neighbour and takes 4:4:4, so the graph is
  ``format=yuvj444p,remap,format=yuvj420p``). ``omnidev_linear_fps``: omnidev's
  default bilinear interpolation.
- ``nonsvp``: a non-single-viewpoint hyperbolic-mirror camera (omnidev.sim's
  dissertation camera at 1920x1920, ``nonsvp-hyper`` file), ``--view
  panorama:2048x512`` nearest-neighbour against the same ``remap`` graph fed its
  maps. (The input frames are the fisheye renders: the speed of a remap does not
  depend on what the pixels show.) Its maps take seconds to build (numerical
  forward projection of every view pixel); that is part of omnidev's command,
  while ffmpeg is handed the maps ready-made: ``stage_split.setup_s`` says how much.

Per case: ``omnidev_fps``, ``ffmpeg_fps`` (frames / median wall time over
``reps`` interleaved runs), ``ratio_vs_ffmpeg`` = omnidev_fps / ffmpeg_fps, both
processes' CPU seconds, and omnidev's per-stage split from ``--stats``: setup
(calibration + maps) and, per pipeline thread, its busy time as a share of the
pipeline's wall time (the decoder's and encoder's own threads are not in it).
``codec_only_fps``: ffmpeg decoding the same input and encoding an output of the
same size with the same codec, quality and threads, the geometry replaced by the
cheapest filter there is (``scale=W:H:flags=neighbor``); ``ratio_ceiling`` =
codec_only_fps / ffmpeg_fps is the ratio an unwarper that costs nothing would
reach with these codecs. On a machine whose cores are all busy (as here, shared),
where wall time follows CPU time, an unwarper that decodes and encodes through
FFmpeg's codecs cannot beat it; on an idle machine only by threading the codecs
better than ffmpeg does.
``ratio_paired``: the median over repetitions of each interleaved pair's ratio
(steadier than the ratio of medians when the machine's load changes during a run).

Environment: ``OMNIDEV_BENCH_CACHE`` (a folder keeping the generated input between
runs), ``OMNIDEV_BENCH_REPS`` (repetitions; 3, or 1 with --quick),
``OMNIDEV_BENCH_CODECS`` (``h264,mjpeg``: a subset runs fewer cases),
``OMNIDEV_BENCH_LINEAR=0`` (skip the ``omnidev_linear_fps`` runs).

Also (single-threaded, 1920x1920 BGR -> 2048x512 panorama, medians):
``api_unwarp_ms`` (``omnidev.unwarp``), ``bare_fixed_remap_ms`` (cv2.remap with
the fixed-point maps), ``bare_float_remap_ms`` (cv2.remap with the float maps),
``api_ratio_vs_fixed_remap`` (target <= 1.05).

``libraries``: wall and CPU (all threads) ms per frame of decoding the input by
cv2.VideoCapture (BGR) and by PyAV (its 4:2:0 planes, 1 and ``threads`` threads;
BGR), and of encoding 2048x512 frames by cv2.VideoWriter (mp4v, all the pip
wheel offers) and by PyAV (mpeg4, libx264 veryfast): why omnidev reads and
writes video files through PyAV (docs/outputs.md).
"""

from __future__ import annotations

import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

import omnidev
from omnidev.camera import Maps, build_maps
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.camfile import write_camera_file
from omnidev.fisheye.models import IdealFisheye
from omnidev.nonsvp.camfile import write_camera_file as write_nonsvp_file
from omnidev.panotable.camfile import save_table
from omnidev.panotable.table import calibrate
from omnidev.sim.fisheye import EquidistantFisheyeCamera
from omnidev.sim.nonsvp import preset_camera
from omnidev.sim.render import render_omni
from omnidev.sim.scene import RoomScene
from omnidev.viewspec import parse_view

SIZE = 1920
# codec -> (ffmpeg's output options, (omnidev's suffix, file: options), description)
CODECS: dict[str, tuple[tuple[str, ...], tuple[str, str], str]] = {
    "h264": (
        ("-c:v", "libx264", "-preset", "veryfast", "-crf", "20"),
        (".mp4", "?crf=20&preset=veryfast"),
        "libx264 preset veryfast crf 20, .mp4 (omnidev's default for .mp4)",
    ),
    "mjpeg": (
        ("-c:v", "mjpeg", "-q:v", "3"),
        (".avi", "?q=3"),
        "Motion JPEG q 3, .avi (omnidev's default for .avi)",
    ),
}
EQUIRECT = "equirect:2048x512"
V360_EQUIRECT = (
    "v360=fisheye:equirect:ih_fov=190:iv_fov=190:pitch=-90:yaw=90:rorder=pyr:w=2048:h=512"
)
FLAT = "perspective:1280x720,fov=90,tilt=45"
V_FOV = 2 * math.degrees(math.atan(math.tan(math.radians(45)) * 720 / 1280))
V360_FLAT = (
    "v360=fisheye:flat:ih_fov=190:iv_fov=190:pitch=-90:yaw=90:roll=-45:rorder=pry:"
    f"h_fov=90:v_fov={V_FOV:.4f}:w=1280:h=720"
)
PANO = "panorama:2048x512"
SHADE_SAMPLE = Path(__file__).resolve().parents[1] / "fixtures" / "omni_room" / "truth_panorama.png"


def _threads() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def _fisheye(folder: Path) -> Path:
    c = (SIZE - 1) / 2
    lens = IdealFisheye("equidistant", 0.5 * SIZE / math.radians(95), c, c)
    path = folder / "fisheye.yml"
    write_camera_file(path, FisheyeCamera(lens, (SIZE, SIZE), MOUNTS["up"], 95.0), force=True)
    return path


def _pano_table(folder: Path) -> Path:
    """bench/unwarp.py's table: exact landmarks of an SVP hyperbolic mirror (eq. 2.1)."""
    a, b = 28.1, 23.4
    c = math.hypot(a, b)
    f = 0.48 * SIZE / (a * a * math.cos(0.2) / (2 * b * c - (b * b + c * c) * math.sin(0.2)))
    rho = np.radians(np.linspace(-75, 11, 24))
    theta = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    r = f * a * a * np.cos(rho) / (2 * b * c - (b * b + c * c) * np.sin(rho))
    uv = np.stack([SIZE / 2 + r * np.cos(theta), SIZE / 2 + r * np.sin(theta)], axis=1)
    xyz = np.stack([np.cos(theta), np.sin(theta), np.tan(rho)], axis=1) * 2.0
    calib = calibrate(uv, xyz, np.zeros(3), (SIZE / 2, SIZE / 2), (SIZE, SIZE))
    path = folder / "panotable.yml.gz"
    save_table(path, calib, force=True)
    return path


def _nonsvp(folder: Path) -> Path:
    path = folder / "nonsvp.yml"
    write_nonsvp_file(path, preset_camera("dissertation", (SIZE, SIZE)), force=True)
    return path


def _input(folder: Path, frames: int) -> Path:
    path = folder / f"fisheye_{SIZE}_{frames}.avi"
    if path.exists():
        return path
    f = 0.5 * SIZE / math.radians(95)
    c = (SIZE - 1) / 2
    sim = EquidistantFisheyeCamera(f, (SIZE, SIZE), (c, c), math.radians(95))
    base = render_omni(sim, RoomScene(seed=3), supersample=1)
    tmp = path.with_suffix(".tmp.avi")
    enc = subprocess.Popen(
        ["ffmpeg", "-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24", "-video_size",
         f"{SIZE}x{SIZE}", "-framerate", "30", "-i", "-", "-c:v", "mjpeg", "-q:v", "3",
         "-pix_fmt", "yuvj420p", str(tmp)], stdin=subprocess.PIPE,
    )  # fmt: skip
    assert enc.stdin is not None
    cv2.setRNGSeed(0)
    noise = np.empty((SIZE, SIZE, 3), np.int16)
    for i in range(frames):
        turn = cv2.getRotationMatrix2D((c, c), 0.3 * i, 1.0)
        img = cv2.warpAffine(base, turn, (SIZE, SIZE)).astype(np.int16)
        cv2.randn(noise, 0, 2)
        enc.stdin.write(np.clip(img + noise, 0, 255).astype(np.uint8).tobytes())
    enc.stdin.close()
    if enc.wait() != 0:
        raise RuntimeError("ffmpeg could not encode the bench input")
    tmp.rename(path)
    return path


def _pgm_maps(maps: Maps, folder: Path, tag: str) -> tuple[Path, Path]:
    """omnidev's maps rounded to whole pixels as 16-bit PGM files for ffmpeg's remap filter."""
    out = []
    for name, m in (("xmap", maps.map_x), ("ymap", maps.map_y)):
        v = np.where(maps.valid, np.rint(m), 65535).clip(0, 65535).astype(np.uint16)
        p = folder / f"{tag}_{name}.pgm"
        cv2.imwrite(str(p), v)
        out.append(p)
    return out[0], out[1]


def _timed(cmd: list[str]) -> tuple[float, float, str]:
    """Wall seconds, child CPU seconds, stderr of one command (which must succeed)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.stderr


def _psnr_valid(a_path: Path, b_path: Path, valid: np.ndarray) -> float:
    ca, cb = cv2.VideoCapture(str(a_path)), cv2.VideoCapture(str(b_path))
    ok1, a = ca.read()
    ok2, b = cb.read()
    if not (ok1 and ok2):
        return float("nan")
    d = (a.astype(np.float64) - b)[valid]
    mse = float(np.mean(d**2))
    return 99.0 if mse == 0 else 10 * math.log10(255**2 / mse)


def _case(
    frames: int,
    omnidev_cmd: list[str],
    ffmpeg_cmd: list[str],
    outputs: tuple[Path, Path],
    valid: np.ndarray,
    reps: int,
    codec_only_cmd: list[str],
    extra: dict[str, list[str]] | None = None,
) -> dict[str, Any]:
    walls: dict[str, list[float]] = {"omnidev": [], "ffmpeg": [], "codec_only": []}
    cpus: dict[str, list[float]] = {"omnidev": [], "ffmpeg": [], "codec_only": []}
    stats: list[dict[str, Any]] = []
    for _ in range(reps):  # interleaved, so that the machine's load hits both alike
        w, c, err = _timed(omnidev_cmd)
        walls["omnidev"].append(w)
        cpus["omnidev"].append(c)
        stats.append(json.loads(err.strip().splitlines()[-1]))
        for key, cmd in (("ffmpeg", ffmpeg_cmd), ("codec_only", codec_only_cmd)):
            w, c, _ = _timed(cmd)
            walls[key].append(w)
            cpus[key].append(c)
    om, ff = float(np.median(walls["omnidev"])), float(np.median(walls["ffmpeg"]))
    s = stats[int(np.argsort(walls["omnidev"])[len(stats) // 2])]
    pipe_wall = s["wall_s"]
    result: dict[str, Any] = {
        "omnidev_fps": round(frames / om, 2),
        "ffmpeg_fps": round(frames / ff, 2),
        "ratio_vs_ffmpeg": round(ff / om, 3),
        "ratio_paired": round(
            float(np.median(np.array(walls["ffmpeg"]) / np.array(walls["omnidev"]))), 3
        ),
        "omnidev_wall_s": [round(x, 2) for x in walls["omnidev"]],
        "ffmpeg_wall_s": [round(x, 2) for x in walls["ffmpeg"]],
        "omnidev_cpu_s": round(float(np.median(cpus["omnidev"])), 2),
        "ffmpeg_cpu_s": round(float(np.median(cpus["ffmpeg"])), 2),
        "codec_only_fps": round(frames / float(np.median(walls["codec_only"])), 2),
        "codec_only_cpu_s": round(float(np.median(cpus["codec_only"])), 2),
        "ratio_ceiling": round(
            float(np.median(walls["ffmpeg"]) / np.median(walls["codec_only"])), 3
        ),
        "omnidev_layout": s["layout"],
        "stage_split": {
            "setup_s": s["setup_s"],
            "pipeline_s": pipe_wall,
            **{
                f"{k.split(':')[0]}_busy": round(v["busy_s"] / pipe_wall, 3)
                for k, v in s["stages"].items()
            },
            **{f"{k.split(':')[0]}_thread_cpu_s": v["cpu_s"] for k, v in s["stages"].items()},
        },
        "psnr_vs_ffmpeg_db": round(_psnr_valid(outputs[0], outputs[1], valid), 2),
    }
    for key, cmd in (extra or {}).items():
        ws = [_timed(cmd)[0] for _ in range(reps)]
        result[key] = round(frames / float(np.median(ws)), 2)
    return result


def _api_vs_bare(camera_path: Path, quick: bool) -> dict[str, Any]:
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        maps = build_maps(omnidev.load_camera(camera_path), parse_view(PANO))
        frame = np.random.default_rng(0).integers(0, 256, (SIZE, SIZE, 3), dtype=np.uint8)
        m1, m2 = maps.fixed_point()
        fns: dict[str, Callable[[], object]] = {
            "api": lambda: omnidev.unwarp(frame, maps),
            "fixed": lambda: cv2.remap(
                frame, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0
            ),
            "float": lambda: cv2.remap(
                frame, maps.map_x, maps.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                borderValue=0,
            ),
        }  # fmt: skip
        for fn in fns.values():
            fn()
        times: dict[str, list[float]] = {k: [] for k in fns}
        for _ in range(7 if quick else 41):
            for k, fn in fns.items():
                t0 = time.perf_counter_ns()
                fn()
                times[k].append((time.perf_counter_ns() - t0) / 1e6)
        med = {k: float(np.median(v)) for k, v in times.items()}
    finally:
        cv2.setNumThreads(threads)
    return {
        "api_unwarp_ms": round(med["api"], 3),
        "bare_fixed_remap_ms": round(med["fixed"], 3),
        "bare_float_remap_ms": round(med["float"], 3),
        "api_ratio_vs_fixed_remap": round(med["api"] / med["fixed"], 4),
    }


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _libraries(src: Path, frames: int, threads: int) -> dict[str, Any]:
    """Decoding and encoding by cv2 and by PyAV: wall and CPU (all threads) ms per frame."""
    import av

    out: dict[str, Any] = {}

    def timed(key: str, fn: Callable[[], int]) -> None:
        c0, t0 = _cpu_s(), time.perf_counter()
        n = fn()
        out[key] = {
            "wall_ms": round((time.perf_counter() - t0) / n * 1e3, 2),
            "cpu_ms": round((_cpu_s() - c0) / n * 1e3, 2),
        }

    def cv2_decode() -> int:
        cap, n = cv2.VideoCapture(str(src)), 0
        while n < frames and cap.read()[0]:
            n += 1
        return n

    def av_decode(fmt: str | None, t: int) -> Callable[[], int]:
        def body() -> int:
            n = 0
            with av.open(str(src)) as c:
                st = c.streams.video[0]
                st.thread_type, st.thread_count = "AUTO", t
                for f in c.decode(st):
                    f.to_ndarray() if fmt is None else f.to_ndarray(format=fmt)
                    n += 1
                    if n == frames:
                        break
            return n

        return body

    timed("decode_cv2_bgr", cv2_decode)
    timed("decode_pyav_planes_1thread", av_decode(None, 1))
    timed(f"decode_pyav_planes_{threads}threads", av_decode(None, threads))
    timed("decode_pyav_bgr_1thread", av_decode("bgr24", 1))
    pano = cv2.resize(cv2.imread(str(SHADE_SAMPLE)) if SHADE_SAMPLE.exists() else
                      np.full((512, 2048, 3), 128, np.uint8), (2048, 512))  # fmt: skip
    n_enc = min(frames, 60)

    def cv2_encode() -> int:
        with tempfile.TemporaryDirectory() as d:
            w = cv2.VideoWriter(f"{d}/a.mp4", cv2.VideoWriter.fourcc(*"mp4v"), 30, (2048, 512))
            for i in range(n_enc):
                w.write(np.roll(pano, 8 * i, axis=1))
            w.release()
        return n_enc

    def av_encode(codec: str, opts: dict[str, str]) -> Callable[[], int]:
        def body() -> int:
            with tempfile.TemporaryDirectory() as d, av.open(f"{d}/a.mp4", "w") as c:
                st = c.add_stream(codec, rate=30, options=opts)
                st.width, st.height, st.pix_fmt, st.thread_count = 2048, 512, "yuv420p", threads
                for i in range(n_enc):
                    img = cv2.cvtColor(np.roll(pano, 8 * i, axis=1), cv2.COLOR_BGR2YUV_I420)
                    for pkt in st.encode(av.VideoFrame.from_ndarray(img, format="yuv420p")):
                        c.mux(pkt)
                for pkt in st.encode(None):
                    c.mux(pkt)
            return n_enc

        return body

    timed("encode_cv2_mp4v", cv2_encode)
    timed("encode_pyav_mpeg4", av_encode("mpeg4", {}))
    timed("encode_pyav_libx264_veryfast", av_encode("libx264", {"preset": "veryfast"}))
    return out


def run(quick: bool = False) -> dict[str, Any]:
    if shutil.which("ffmpeg") is None:
        raise RuntimeError("bench video needs ffmpeg (apt-get install ffmpeg)")
    frames = 60 if quick else 300
    reps = int(os.environ.get("OMNIDEV_BENCH_REPS", 1 if quick else 3))
    codecs = os.environ.get("OMNIDEV_BENCH_CODECS", "h264,mjpeg").split(",")
    unknown = sorted(set(codecs) - set(CODECS))
    if unknown:
        raise ValueError(f"OMNIDEV_BENCH_CODECS: unknown {unknown} (known: {sorted(CODECS)})")
    linear = os.environ.get("OMNIDEV_BENCH_LINEAR", "1") != "0"
    threads = _threads()
    cache = os.environ.get("OMNIDEV_BENCH_CACHE")
    with tempfile.TemporaryDirectory(prefix="omnidev-bench-video-") as tmp:
        work = Path(tmp)
        data = Path(cache) if cache else work
        data.mkdir(parents=True, exist_ok=True)
        src = _input(data, frames)
        fisheye = _fisheye(work)
        table = _pano_table(work)
        nonsvp = _nonsvp(work)
        omnidev_bin = str(Path(sys.executable).parent / "omnidev")
        t = str(threads)

        result: dict[str, Any] = {
            "input": f"{frames} frames {SIZE}x{SIZE} MJPEG q3 yuvj420p",
            "codecs": {k: CODECS[k][2] for k in codecs},
            "threads": threads,
            "reps": reps,
            "load_avg_1min_start": round(os.getloadavg()[0], 2),
        }
        cam = omnidev.load_camera(fisheye)
        pano_maps = {
            "pano": build_maps(omnidev.load_camera(table), parse_view(PANO)),
            "nonsvp": build_maps(omnidev.load_camera(nonsvp), parse_view(PANO)),
        }
        valid = {
            "eq": build_maps(cam, parse_view(EQUIRECT)).valid,
            "flat": build_maps(cam, parse_view(FLAT)).valid,
            **{k: m.valid for k, m in pano_maps.items()},
        }
        pgm = {k: _pgm_maps(m, work, k) for k, m in pano_maps.items()}
        del pano_maps
        for codec in codecs:
            ff_args, (suffix, query), _ = CODECS[codec]
            tag = "" if codec == "h264" else f"_{codec}"

            def om(camera: Path, view: str, out: Path, *more: str, query: str = query) -> list[str]:
                return [
                    omnidev_bin, "unwarp", str(src), "--camera", str(camera), "--view", view,
                    "-o", f"file:{out}{query}", "--force", "--threads", t, "--stats", *more,
                ]  # fmt: skip

            def ff(out: Path, *graph: str, ff_args: tuple[str, ...] = ff_args) -> list[str]:
                return ["ffmpeg", "-v", "error", "-y", "-threads", t, "-i", str(src), *graph,
                        "-filter_threads", t, "-filter_complex_threads", t, *ff_args,
                        "-threads", t, str(out)]  # fmt: skip

            def ff_remap(
                out: Path, maps: tuple[Path, Path], ff_args: tuple[str, ...] = ff_args
            ) -> list[str]:
                graph = "[0:v]format=yuvj444p[s];[s][1:v][2:v]remap,format=yuvj420p[o]"
                return [
                    "ffmpeg", "-v", "error", "-y", "-threads", t, "-i", str(src), "-i",
                    str(maps[0]), "-i", str(maps[1]), "-filter_complex", graph, "-map", "[o]",
                    "-filter_threads", t, "-filter_complex_threads", t, *ff_args, "-threads", t,
                    str(out),
                ]  # fmt: skip

            def codec_only(size: str, suffix: str = suffix) -> list[str]:
                return ff(work / f"codec_only{suffix}", "-vf", f"scale={size}:flags=neighbor")

            o1, f1 = work / f"eq_omnidev{suffix}", work / f"eq_ffmpeg{suffix}"
            result[f"fisheye_equirect{tag}"] = _case(
                frames, om(fisheye, EQUIRECT, o1), ff(f1, "-vf", V360_EQUIRECT), (o1, f1),
                valid["eq"], reps, codec_only("2048:512"),
            )  # fmt: skip
            o2, f2 = work / f"flat_omnidev{suffix}", work / f"flat_ffmpeg{suffix}"
            result[f"fisheye_flat{tag}"] = _case(
                frames, om(fisheye, FLAT, o2), ff(f2, "-vf", V360_FLAT), (o2, f2),
                valid["flat"], reps, codec_only("1280:720"),
            )  # fmt: skip
            for key, camera in (("pano", table), ("nonsvp", nonsvp)):
                o3, f3 = work / f"{key}_omnidev{suffix}", work / f"{key}_ffmpeg{suffix}"
                o4 = work / f"{key}_linear{suffix}"
                name = "pano_table" if key == "pano" else "nonsvp"
                result[f"{name}{tag}"] = _case(
                    frames, om(camera, PANO, o3, "--interpolation", "nearest"),
                    ff_remap(f3, pgm[key]), (o3, f3), valid[key], reps, codec_only("2048:512"),
                    {"omnidev_linear_fps": om(camera, PANO, o4)} if linear else None,
                )  # fmt: skip
        result["load_avg_1min_end"] = round(os.getloadavg()[0], 2)
        result.update(_api_vs_bare(table, quick))
        result["libraries"] = _libraries(src, 60 if quick else 150, threads)
    return result
