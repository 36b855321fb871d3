"""Outputs under signals and races.

No temporary survives SIGTERM/SIGINT at any moment of a long unwarp (from its first
progress report on); of two runs writing one new output without --force exactly one
succeeds; a temporary left by a killed run is removed by the next run writing that output.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.atomic import TEMP_TAG, atomic_path, commit_temporary, make_temporary
from omnidev.errors import OutputError

REPO = Path(__file__).resolve().parents[1]
OMNI = REPO / "fixtures" / "omni_room"
FRAMES = 1200  # long enough that the signals (at 0-3 s) land while it works on a quiet machine


@pytest.fixture(scope="module")
def camera(tmp_path_factory) -> Path:
    from omnidev.cli.main import main

    out = tmp_path_factory.mktemp("cam") / "cam.yml.gz"
    argv = ["calibrate", "pano-table", str(OMNI / "landmarks.csv"), "--mirror-center",
            "0.3,-0.2,1.2", "--image", str(OMNI / "omni_0000.png"), "--image-center", "detect",
            "--table-size", "256x64", "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    return out


def temporaries(folder: Path) -> list[Path]:
    return [p for p in folder.iterdir() if TEMP_TAG in p.name]


def _unwarp(folder: Path, camera: Path, out: str, *extra: str) -> subprocess.Popen[str]:
    argv = [sys.executable, "-m", "omnidev.cli.main", "unwarp",
            f"video:{OMNI / 'omni.avi'}?loop=1", "--camera", str(camera), "--frames", str(FRAMES),
            "--view", "panorama:1024x256", "-o", out, *extra]  # fmt: skip
    return subprocess.Popen(
        argv, cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def test_no_temporary_after_sigterm_at_random_times(tmp_path, camera):
    rng = random.Random(14)
    runs = []
    for pair in range(11):  # two runs at a time (2 cores), 22 runs in all
        started = []
        for k in (2 * pair, 2 * pair + 1):
            folder = tmp_path / f"run{k}"
            folder.mkdir()
            sig = signal.SIGINT if k % 4 == 3 else signal.SIGTERM
            started.append((k, folder, sig, _unwarp(folder, camera, "pano.mp4")))
        for _, _, _, proc in started:
            assert proc.stderr is not None
            proc.stderr.read(1)  # it reports progress: the command runs (imports are done)
        t0 = time.monotonic()
        delays = sorted((rng.uniform(0.0, 3.0), i) for i in range(2))
        for delay, i in delays:
            time.sleep(max(0.0, t0 + delay - time.monotonic()))
            started[i][3].send_signal(started[i][2])
        for (k, folder, sig, proc), delay in zip(
            started, [d for d, _ in sorted(delays, key=lambda x: x[1])], strict=True
        ):
            said, err = proc.communicate(timeout=120)
            left = temporaries(folder)
            out = folder / "pano.mp4"
            runs.append((k, sig, delay, proc.returncode, out.exists()))
            assert not left, f"run {k}: {sig.name} after {delay:.2f} s left {left}: {err[-500:]}"
            assert "Traceback" not in err, err
            if proc.returncode == 0:  # finished before the signal: a complete video
                assert cv2.VideoCapture(str(out)).get(cv2.CAP_PROP_FRAME_COUNT) == FRAMES
            else:
                assert proc.returncode in (128 + sig, -sig, 130), (proc.returncode, err)
                if out.exists():  # the signal landed after the commit: a whole video
                    assert f"wrote pano.mp4 ({FRAMES} frames)" in said, (said, err)
                    assert cv2.VideoCapture(str(out)).get(cv2.CAP_PROP_FRAME_COUNT) == FRAMES
    interrupted = [r for r in runs if r[3] != 0 and not r[4]]
    print(f"\n{len(runs)} runs, {len(interrupted)} interrupted mid-run, 0 temporaries left")
    assert len(interrupted) >= 15  # the signals did land while it worked


def test_two_writers_of_one_output_exactly_one_succeeds(tmp_path, camera):
    for k in range(3):
        folder = tmp_path / f"pair{k}"
        folder.mkdir()
        argv = ["--frames", "30"]
        procs = [_unwarp(folder, camera, "pano.avi", *argv) for _ in range(2)]
        results = []
        for p in procs:
            _, err = p.communicate(timeout=120)  # stdout piped too: read both, then the code
            results.append((p.returncode, err))
        codes = sorted(rc for rc, _ in results)
        assert codes == [0, 2], results
        loser = next(err for rc, err in results if rc == 2)
        assert "pano.avi exists" in loser and "Traceback" not in loser
        assert cv2.VideoCapture(str(folder / "pano.avi")).get(cv2.CAP_PROP_FRAME_COUNT) == 30
        assert not temporaries(folder)


def test_commit_is_create_exclusive_without_force(tmp_path):
    target = tmp_path / "out.txt"
    first, second = make_temporary(target), make_temporary(target)
    first.write_text("first")
    second.write_text("second")
    commit_temporary(first, target, force=False)
    with pytest.raises(OutputError, match="exists"):
        commit_temporary(second, target, force=False)
    assert target.read_text() == "first" and not temporaries(tmp_path)
    third = make_temporary(target)
    third.write_text("third")
    commit_temporary(third, target, force=True)
    assert target.read_text() == "third" and not temporaries(tmp_path)


def test_stale_temporaries_of_a_killed_run_are_removed(tmp_path, capsys):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".out.{TEMP_TAG}{dead.pid}-abc123.yml.gz"
    stale.write_bytes(b"half")
    alive = tmp_path / f".out.{TEMP_TAG}{os.getpid()}-xyz789.yml.gz"
    alive.write_bytes(b"in progress")  # a live process's: kept
    with atomic_path(tmp_path / "out.yml.gz") as tmp:
        tmp.write_bytes(b"done")
    assert not stale.exists() and alive.exists()
    assert f"removed {stale}" in capsys.readouterr().err
    assert (tmp_path / "out.yml.gz").read_bytes() == b"done"


def test_output_that_is_a_folder_is_a_clean_error(tmp_path, camera):
    from omnidev.cli.main import main

    img = tmp_path / "omni.png"
    cv2.imwrite(str(img), np.zeros((640, 640, 3), np.uint8))
    (tmp_path / "out.png").mkdir()
    argv = ["unwarp", str(img), "--camera", str(camera), "--view", "panorama:64x16",
            "-o", str(tmp_path / "out.png"), "--force"]  # fmt: skip
    assert main(argv) == 2
