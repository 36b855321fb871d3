"""Bad input on the command line: one clear line naming the file/row/key, exit 2, no traceback."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from omnidev.cli.main import main

A, B = 28.1, 23.4
C = math.hypot(A, B)


def write_landmarks(path: Path, n: int = 12, extra: str = "") -> None:
    rho = np.radians(np.linspace(-70, 10, n))
    theta = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 300 * A * A * np.cos(rho) / (2 * B * C - (B * B + C * C) * np.sin(rho))
    lines = ["u,v,X,Y,Z"]
    for t, rh, rr in zip(theta, rho, r, strict=True):
        lines.append(
            f"{320 + rr * np.cos(t):.4f},{320 + rr * np.sin(t):.4f},"
            f"{2 * np.cos(t):.4f},{2 * np.sin(t):.4f},{1 + 2 * np.tan(rh):.4f}"
        )
    path.write_text("\n".join(lines) + "\n" + extra)


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "omnidev.cli.main", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def calibrate_args(csv: Path, out: Path) -> list[str]:
    return [
        "calibrate",
        "pano-table",
        str(csv),
        "--mirror-center",
        "0,0,1",
        "--image-center",
        "320,320",
        "--image-size",
        "640x640",
        "-o",
        str(out),
    ]


def test_calibrate_writes_table_and_plot(tmp_path, capsys):
    csv = tmp_path / "lm.csv"
    write_landmarks(csv)
    out = tmp_path / "cam.yml"
    assert main(calibrate_args(csv, out)) == 0
    text = capsys.readouterr().out
    assert "radial fit RMS" in text and out.exists() and (tmp_path / "cam_fit.png").exists()
    png = (tmp_path / "cam_fit.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    # existing outputs are kept without --force
    assert main(calibrate_args(csv, out)) == 2
    assert "exists; pass --force" in capsys.readouterr().err
    assert main([*calibrate_args(csv, out), "--force"]) == 0


@pytest.mark.parametrize(
    "content,expect",
    [
        ("u,v,X,Y\n1,2,3,4\n", "line 1: header lacks column(s) Z"),
        ("u,v,X,Y,Z\n1,2,3,4,5\n1,2,abc,4,5\n", "line 3: column X is 'abc', not a number"),
        ("u,v,X,Y,Z\n1,2,3,4,5\n1,2,3,4\n", "line 3: 4 fields, the header has 5"),
        ("u,v,X,Y,Z\n1,2,3,4,nan\n", "line 2: column Z is not finite"),
        # fuzz seed 19: a 30-digit group overflowed numpy's intp (a traceback)
        (
            "u,v,X,Y,Z,group\n1,2,3,4,5,123456789012345678901234567890\n",
            "line 2: column group is 123456789012345678901234567890; |group| must be <= 1e+09",
        ),
        ("u,v,X,Y,Z\n", "no landmark rows"),
        ("u,v,X,Y,Z\n" + "1,2,3,4,5\n" * 4, "4 landmarks: the 4th-degree radial function needs"),
        ("u,v,X,Y,Z\n" + "".join(f"{i},2,3,4,5\n" for i in range(8)), "distinct elevations"),
    ],
)
def test_bad_landmark_files(tmp_path, content, expect):
    csv = tmp_path / "lm.csv"
    csv.write_text(content)
    res = run_cli(*calibrate_args(csv, tmp_path / "cam.yml"))
    assert res.returncode == 2
    assert expect in res.stderr
    assert "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "cam.yml").exists()


def test_missing_landmark_file_and_unwritable_output(tmp_path):
    res = run_cli(*calibrate_args(tmp_path / "nope.csv", tmp_path / "cam.yml"))
    assert res.returncode == 2 and "nope.csv: landmark file not found" in res.stderr
    csv = tmp_path / "lm.csv"
    write_landmarks(csv)
    res = run_cli(*calibrate_args(csv, tmp_path / "no_dir" / "cam.yml"))
    assert res.returncode == 2 and "does not exist" in res.stderr
    if os.geteuid() != 0:  # root writes anywhere
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        res = run_cli(*calibrate_args(csv, ro / "cam.yml"))
        assert res.returncode == 2 and "not writable" in res.stderr


def test_unwarp_rejects_other_kinds_and_versions(tmp_path):
    import cv2

    img = tmp_path / "omni.png"
    cv2.imwrite(str(img), np.zeros((640, 640, 3), np.uint8))
    for name, kind, version, expect in [
        ("other.yml", "mystery-kind", 1, "no plugin for camera kind 'mystery-kind'"),
        ("old.yml", "pano-table", 7, "pano-table format version 7"),
    ]:
        p = tmp_path / name
        fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
        fs.write("kind", kind)
        fs.write("format_version", version)
        fs.release()
        res = run_cli(
            "unwarp",
            str(img),
            "--camera",
            str(p),
            "--view",
            "panorama:64x16",
            "-o",
            str(tmp_path / "o.png"),
        )
        assert res.returncode == 2, res.stderr
        assert expect in res.stderr and "Traceback" not in res.stderr
    res = run_cli(
        "unwarp",
        str(img),
        "--camera",
        str(tmp_path / "other.yml"),
        "--view",
        "panorama:64x16",
        "-o",
        str(tmp_path / "o.png"),
    )
    assert "installed: " in res.stderr and "pano-table" in res.stderr


def test_unwarp_bad_view_and_output_pairs(tmp_path):
    csv = tmp_path / "lm.csv"
    write_landmarks(csv)
    cam = tmp_path / "cam.yml"
    assert main(calibrate_args(csv, cam)) == 0
    import cv2

    img = tmp_path / "omni.png"
    cv2.imwrite(str(img), np.full((640, 640, 3), 128, np.uint8))
    res = run_cli(
        "unwarp",
        str(img),
        "--camera",
        str(cam),
        "--view",
        "blob:10x10",
        "-o",
        str(tmp_path / "o.png"),
    )
    assert res.returncode == 2 and "unknown kind 'blob'" in res.stderr
    res = run_cli(
        "unwarp",
        str(img),
        "--camera",
        str(cam),
        "--view",
        "panorama:64x16",
        "--view",
        "panorama:32x8",
        "-o",
        str(tmp_path / "o.png"),
    )
    assert res.returncode == 2 and "one output per view" in res.stderr
    res = run_cli(
        "unwarp",
        str(img),
        "--camera",
        str(cam),
        "--view",
        "panorama:64x16",
        "-o",
        str(tmp_path / "o.xyz"),
    )
    assert res.returncode == 2 and "unknown output type .xyz" in res.stderr
    res = run_cli(
        "unwarp",
        str(img),
        "--camera",
        str(cam),
        "--camera-option",
        "lookup=cubic",
        "--view",
        "panorama:64x16",
        "-o",
        str(tmp_path / "o.png"),
    )
    assert res.returncode == 2 and "lookup='cubic'" in res.stderr
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((100, 100, 3), np.uint8))
    res = run_cli(
        "unwarp",
        str(small),
        "--camera",
        str(cam),
        "--view",
        "panorama:64x16",
        "-o",
        str(tmp_path / "o.png"),
    )
    assert res.returncode == 2 and "is 100x100; the calibration is for 640x640" in res.stderr
    assert not (tmp_path / "o.png").exists()


def test_calibration_text_value_that_is_not_utf8(tmp_path):
    # found by the full fuzz sweep: OpenCV reads the byte into the 'kind' string, whose
    # decoding then raised UnicodeDecodeError (a traceback) instead of a clean error
    import cv2

    img = tmp_path / "omni.png"
    cv2.imwrite(str(img), np.zeros((64, 64, 3), np.uint8))
    bad = tmp_path / "cam.yml"
    bad.write_bytes(b"%YAML 1.2\n---\nkind: fisheye\xde\nformat_version: 1\n")
    res = run_cli("unwarp", str(img), "--camera", str(bad), "--view", "panorama:64x16",
                  "-o", str(tmp_path / "o.png"))  # fmt: skip
    assert res.returncode == 2, res.stderr
    assert "Traceback" not in res.stderr
    assert f"{bad}: text key 'kind' is not UTF-8 text" in res.stderr
    assert res.stderr.count(str(bad)) == 1  # named once, not once per layer
