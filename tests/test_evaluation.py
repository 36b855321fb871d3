"""The evaluation framework (omnidev.evaluation): tasks, pooling, classes, refusals, errors, CLI."""

from __future__ import annotations

import contextlib
import json
import math
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from omnidev.cli.main import main
from omnidev.errors import OmnidevError
from omnidev.evaluation.framework import (
    SceneResult,
    Task,
    by_class,
    evaluate,
    load_task,
    merge_reports,
    pooled,
    refusals,
    run_one,
    stats,
    task_names,
    typed_options,
)


def _fake(seed: int, options: object, outdir: Path | None) -> SceneResult:
    if seed == 3:
        raise ZeroDivisionError("boom")
    r = SceneResult(seed, classes={"size": "big" if seed % 2 else "small"})
    if seed == 4:
        r.status, r.message = "refused", "too dark"
        return r
    r.metrics["err"] = float(seed)
    r.counts["hits"] = 2
    return r


FAKE = Task("fake", "a test task", _fake, options={"k": 1, "on": False}, headline=("err",))


def test_stats_and_worst_on_known_values() -> None:
    s = stats([1.0, 2.0, 3.0, math.nan, 10.0])
    assert s["n"] == 4 and s["median"] == 2.5 and s["max"] == 10.0
    assert s["mean"] == 4.0 and s["p95"] == pytest.approx(8.95)
    assert stats([])["median"] is None


def test_evaluate_pools_refusals_errors_and_classes() -> None:
    doc = evaluate(FAKE, scenes=6, seed=0, progress=False)
    p = doc["pooled"]
    assert (p["scenes"], p["ok"], p["refused"], p["errors"]) == (6, 4, 1, 1)
    assert p["metrics"]["err"]["max"] == 5.0 and p["counts"]["hits"] == 8
    assert [w["seed"] for w in p["worst"]["err"]][:2] == [5, 2]
    assert doc["refusals"] == [{"message": "too dark", "count": 1, "seeds": [4]}]
    assert (
        doc["errors"][0]["seeds"] == [3]
        and "ZeroDivisionError: boom" in doc["errors"][0]["message"]
    )
    cls = doc["classes"]["size"]
    assert cls["big"]["scenes"] == 2 and cls["?"]["errors"] == 1  # an error has no classes
    assert cls["small"]["refused"] == 1 and cls["small"]["metrics"]["err"]["max"] == 2.0
    assert [r["seed"] for r in doc["per_scene"]] == list(range(6))


def test_pooling_helpers_agree() -> None:
    rs = [run_one(FAKE, s, {}, None) for s in range(6)]
    assert pooled(rs)["refused"] == 1
    assert refusals(rs, "error")[0]["count"] == 1
    assert by_class(rs, ("err",))["size"]["big"]["metrics"]["err"]["n"] == 2


def test_reports_of_chunks_merge_into_the_whole_run() -> None:
    whole = evaluate(FAKE, scenes=8, seed=0, progress=False)
    parts = [evaluate(FAKE, scenes=n, seed=s, progress=False) for s, n in ((5, 3), (0, 5))]
    doc = merge_reports(FAKE, [("b", json.loads(json.dumps(parts[0]))), ("a", parts[1])])
    for key in ("pooled", "refusals", "errors", "classes", "seed_range", "scenes"):
        a, b = doc[key], whole[key]
        if key == "pooled":
            a, b = (dict(x, seconds_per_scene=None) for x in (a, b))
        assert a == b, key
    assert doc["merged_from"] == ["b", "a"]
    with pytest.raises(OmnidevError, match="a: scene seed 0 is also in b"):
        merge_reports(FAKE, [("b", parts[1]), ("a", parts[1])])
    with pytest.raises(OmnidevError, match="x: task options .* differ"):
        merge_reports(FAKE, [("b", parts[0]), ("x", dict(parts[1], options={"k": 2}))])
    with pytest.raises(OmnidevError, match="y: not an 'omnidev eval fake' report"):
        merge_reports(FAKE, [("y", [1, 2])])  # type: ignore[list-item]


def test_options_are_typed_and_checked() -> None:
    assert typed_options(FAKE, {"k": "3", "on": "yes"}) == {"k": 3, "on": True}
    with pytest.raises(OmnidevError, match="unknown option 'x'.*options: k, on"):
        typed_options(FAKE, {"x": "1"})
    with pytest.raises(OmnidevError, match="option k='a' is not a int"):
        typed_options(FAKE, {"k": "a"})


def test_tasks_are_found_by_module_name() -> None:
    assert "screen" in task_names()
    assert load_task("screen").name == "screen"
    with pytest.raises(OmnidevError, match="unknown evaluation task 'nope'; known: .*screen"):
        load_task("nope")


def test_cli_lists_tasks_and_rejects_bad_options(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--list"]) == 0
    assert "screen:" in capsys.readouterr().out
    assert main(["eval", "screen", "--opt", "nope=1", "--scenes", "1"]) == 2
    err = capsys.readouterr().err
    assert "unknown option 'nope'" in err and len(err.strip().splitlines()) == 1
    assert main(["eval", "screen", "--write", "x"]) == 2
    assert "--write needs --scene-seed" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["laser", "--opt", "frames=0"], "option frames='0' must be 10..100000"),
        (["laser", "--opt", "beam_channels=7"], "need beam_channels 1 or 3, got 7"),
        (["laser", "--opt", "halo=-5"], "need halo >= 0"),
        (
            ["laser", "--opt", "position=zz"],
            "position must be 'beam', 'centroid' or 'fit', got 'zz'",
        ),
        (["laser", "--opt", "hold_spot=3"], "option hold_spot=3 must be 0 or 1"),
        (["laser", "--opt", "method=zz"], "option method='zz'; choose from colour, white-core"),
        (["laser", "--opt", "cache=/proc/omnidev-none"], "cache /proc/omnidev-none: No such"),
        (  # refused under any limit (2 TiB); an explicit one, as OMNIDEV_MAX_MEMORY=0 lifts it
            ["laser", "--opt", "frames=100000", "--max-memory", "64G"],
            "task laser: frames=100000 (a 1920x1080 scene",
        ),
        (["mouse", "--opt", "frames=0"], "option frames='0' must be 2..100000"),
        (["screen", "--scene-seed", "5", "--write", "/proc/omnidev-none"], "--write /proc/omnidev"),
    ],
)
def test_cli_refuses_options_no_scene_could_run(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Options every scene would refuse are one-line errors before any scene runs (they
    were one error per scene, exit 1, and ``--write`` said it wrote what it could not)."""
    assert main(["eval", *args, "--scenes", "1", "--no-progress"]) == 2
    captured = capsys.readouterr()
    assert message in captured.err and len(captured.err.strip().splitlines()) == 1
    assert "wrote" not in captured.out


def test_cli_json_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r.json"
    rc = main(["eval", "screen", "--scenes", "1", "--seed", "1003", "--json", "-o", str(out)])
    text = capsys.readouterr().out
    doc = json.loads(text)
    assert rc == 0 and json.loads(out.read_text()) == doc
    assert doc["seed_range"] == [1003, 1003] and len(doc["per_scene"]) == 1
    assert doc["summary"]["acceptance"][0]["bound"] == "<= 0.01"
    # a saved report merges (here with nothing else) into the same figures
    assert main(["eval", "screen", "--merge", str(out), "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["pooled"]["metrics"] == doc["pooled"]["metrics"]
    assert again["summary"] == doc["summary"]
    assert main(["eval", "screen", "--merge", str(out), str(out)]) == 2
    assert "is also in" in capsys.readouterr().err
    assert main(["eval", "screen", "--merge", str(tmp_path / "none.json")]) == 2
    assert "none.json: no such report" in capsys.readouterr().err


def test_cli_replays_one_scene_and_writes_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "scene"
    rc = main(
        ["eval", "screen", "--scene-seed", "1003", "--write", str(out), "--opt", "coded=false"]
    )
    text = capsys.readouterr().out
    assert rc == 0 and "scene 1003: ok" in text and "radial.rms" in text
    for name in ("white.png", "black.png", "dots.png"):
        assert (out / name).is_file()
    truth = json.loads((out / "truth.json").read_text())
    assert len(truth["image_points"]) == len(truth["screen_points"]) > 1000
    # the written truth file is one `calibrate screen --truth` takes
    rc = main(
        [
            "calibrate",
            "screen",
            "--white",
            str(out / "white.png"),
            "--black",
            str(out / "black.png"),
            "--dots",
            str(out / "dots.png"),
            "--layout",
            str(out / "layout.json"),
            "-o",
            str(tmp_path / "c.yml"),
            "--truth",
            str(out / "truth.json"),
        ]
    )
    assert rc == 0 and "truth points:" in capsys.readouterr().out


def _children(pid: int) -> set[int]:
    """The live child processes of ``pid`` (from /proc)."""
    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        with contextlib.suppress(OSError):
            out |= {int(c) for c in (task / "children").read_text().split()}
    return out


def test_sigterm_ends_a_pooled_eval_and_its_workers() -> None:
    """``omnidev eval --jobs 2`` told to stop mid-run (SIGTERM, as systemd or a CI timeout
    does) exits 143 within seconds, leaves no worker behind and prints no traceback: the
    workers take the kernel's default action, not the CLI's handler (with it, each worker
    printed a KeyboardInterrupt-style traceback, and once one was left waiting for work
    for ever with the parent in Pool.terminate)."""
    import signal
    import subprocess
    import sys
    import time

    exe = Path(sys.executable).parent / "omnidev"
    cmd = [str(exe), "eval", "screen", "--scenes", "8", "--seed", "1003", "--jobs", "2"]
    cmd.append("--no-progress")
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        workers: set[int] = set()
        while len(workers) < 2 and time.monotonic() < deadline and proc.poll() is None:
            workers = _children(proc.pid)
            time.sleep(0.05)
        assert len(workers) == 2, f"no pool of 2 workers: {workers}, rc {proc.poll()}"
        time.sleep(1.0)  # the workers are inside their first scenes
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    print(f"SIGTERM to exit: {took:.2f} s")
    assert proc.returncode == 143, err.decode(errors="replace")[-2000:]
    assert took < 30.0
    for pid in workers:
        assert _zombie_or_gone(pid), f"worker {pid} left"
    assert "Traceback" not in err.decode(errors="replace")


def _zombie_or_gone(pid: int) -> bool:
    """True when process ``pid`` has ended (gone, or a zombie not yet reaped)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1].startswith("Z")
    except (OSError, IndexError):
        return True


def test_laser_cache_is_npy_and_json_read_back_and_a_bad_file_is_rendered_again(
    tmp_path: Path,
) -> None:
    """The laser task's frame cache holds no pickle; the counts from the cache equal the
    counts from rendering; a damaged cache file is rendered again, not an error."""
    task = load_task("laser")
    opts = {"frames": 12, "compare": False, "cache": str(tmp_path)}
    first = run_one(task, 1006, opts, None)  # 320x240: the smallest camera
    assert first.status == "ok", first.message
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["laser-1006-12.json", "laser-1006-12.npy"]
    frames = np.load(tmp_path / "laser-1006-12.npy", allow_pickle=False)
    assert frames.shape == (12, 240, 320, 3) and frames.dtype == np.uint8
    again = run_one(task, 1006, opts, None)
    assert again.counts == first.counts
    assert json.dumps(again.metrics, sort_keys=True) == json.dumps(first.metrics, sort_keys=True)
    (tmp_path / "laser-1006-12.npy").write_bytes(b"\x93NUMPY truncated")
    redone = run_one(task, 1006, opts, None)
    assert redone.status == "ok" and redone.counts == first.counts
    assert np.array_equal(np.load(tmp_path / "laser-1006-12.npy"), frames)


def test_laser_cache_that_cannot_be_written_leaves_the_scene_evaluated(tmp_path: Path) -> None:
    """A cache write that fails (here a real kernel limit on file size, EFBIG, as a full
    disk gives ENOSPC) costs the cache, not the scene: the scene is evaluated from the
    frames in memory, one line says it was not cached, and no partial file is left."""
    cache = tmp_path / "cache"
    cache.mkdir()

    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit: EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (1 << 20, 1 << 20))

    cmd = [sys.executable, "-m", "omnidev.cli.main", "eval", "laser", "--scenes", "1"]
    cmd += ["--seed", "1006", "--jobs", "1", "--opt", "frames=12", "--opt", "compare=0"]
    cmd += ["--opt", f"cache={cache}"]
    # 12 frames of 320x240: 2.8 MB of cache against a 1 MiB limit
    run = subprocess.run(cmd, capture_output=True, text=True, preexec_fn=limit, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "scene 1006 not cached (File too large)" in run.stderr
    assert "ok 1, refused 0, errors 0" in run.stdout
    assert sorted(p.name for p in cache.iterdir()) == []
