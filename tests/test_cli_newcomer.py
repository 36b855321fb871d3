"""The newcomer's path: --version, negative values after a space, help texts that list
every view kind and key, sim options with help and defaults, a bounded memory estimate."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import omnidev
from omnidev.cli.main import build_parser, main
from omnidev.viewspec import _KEYS


def test_version():
    res = subprocess.run(
        [sys.executable, "-m", "omnidev.cli.main", "--version"], capture_output=True, text=True
    )
    assert res.returncode == 0 and res.stdout.strip() == f"omnidev {omnidev.__version__}"


def test_negative_values_after_a_space():
    args = build_parser().parse_args(
        ["calibrate", "pano-table", "lm.csv", "--mirror-center", "-0.3,0,1",
         "--elevation-range", "-50,10", "-o", "c.yml"]
    )  # fmt: skip
    assert args.mirror_center == "-0.3,0,1" and args.elevation_range == "-50,10"
    args = build_parser().parse_args(["sim", "nonsvp", "out", "--T", "-1,0,88"])
    assert args.T == "-1,0,88"


def test_unwarp_help_lists_every_view_kind_and_key(capsys):
    with pytest.raises(SystemExit):
        main(["unwarp", "--help"])
    text = capsys.readouterr().out
    for kind, keys in _KEYS.items():
        assert f"{kind}:WxH" in text, kind
        for key in keys:
            assert f"{key}=" in text, (kind, key)
    assert "degrees" in text and "calibration's unit" in text


def test_bench_help_lists_every_benchmark_with_what_it_measures(capsys):
    from omnidev.cli.bench_cmd import available, bench_dir

    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    text = capsys.readouterr().out
    names = sorted(p.stem for p in bench_dir().glob("*.py") if not p.stem.startswith("_"))
    assert names == available() and len(names) >= 9
    for name in names:
        line = next(ln for ln in text.splitlines() if ln.strip().startswith(name + " "))
        assert len(line.split()) > 4, line  # the name, then its docstring's first sentence
    assert "Laser pointer speed at 1280x720" in text


def test_max_memory_help_says_the_real_default(capsys):
    with pytest.raises(SystemExit):
        main(["unwarp", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "half the physical memory" in text and "default 1G" not in text


@pytest.mark.parametrize("what", ["omni", "blob", "mouse", "screen", "nonsvp", "chessboard"])
def test_sim_options_have_help_and_defaults(capsys, what):
    with pytest.raises(SystemExit):
        main(["sim", what, "--help"])
    text = capsys.readouterr().out
    assert "--seed" in text and "(default: 0)" in text


def test_every_command_has_max_memory_and_refuses_a_huge_view(tmp_path, capsys):
    import cv2
    import numpy as np

    img = tmp_path / "fish.png"
    cv2.imwrite(str(img), np.zeros((64, 64, 3), np.uint8))
    kalibr = tmp_path / "k.yaml"
    kalibr.write_text(
        "cam0:\n  camera_model: pinhole\n  intrinsics: [30, 30, 32, 32]\n"
        "  distortion_model: equidistant\n  distortion_coeffs: [0, 0, 0, 0]\n"
        "  resolution: [64, 64]\n"
    )
    cam = tmp_path / "fish.yml"
    assert main(["calibrate", "import", str(kalibr), "-o", str(cam)]) == 0
    argv = ["unwarp", str(img), "--camera", str(cam), "--view", "perspective:20000x20000",
            "-o", str(tmp_path / "v.png"), "--max-memory", "1G"]  # fmt: skip
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "needs about" in err and "GiB" in err and "--max-memory" in err
    assert main([*argv, "--max-memory", "0.001G"]) == 2  # a limit below what is in use


def test_bench_says_it_runs_while_it_runs(tmp_path, monkeypatch, capsys):
    """A benchmark that takes a while: a start line, "so far" lines while it works and
    its wall time at the end, on stderr; the figures alone on stdout."""
    from omnidev.cli import bench_cmd

    (tmp_path / "nap.py").write_text(
        '"""Sleeps."""\nimport time\n\n\ndef run(quick=False):\n'
        "    time.sleep(0.35)\n    return {'slept_ms': 350.0}\n"
    )
    monkeypatch.setenv("OMNIDEV_BENCH_DIR", str(tmp_path))
    monkeypatch.setattr(bench_cmd, "HEARTBEAT_S", 0.1)
    assert main(["bench", "nap", "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out) == {"slept_ms": 350.0}
    lines = err.splitlines()
    assert lines[0] == "omnidev bench nap: running (a full run takes minutes; --quick is short)"
    assert 2 <= sum(line.endswith("so far") for line in lines) <= 4
    assert lines[-1] == "omnidev bench nap: done in 0 s"
