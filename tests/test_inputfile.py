"""omnidev.inputfile's safe reader: what it refuses, and the one line it says for each."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from omnidev.errors import ConfigError
from omnidev.inputfile import loads_json, loads_toml, not_a_file, read_bytes


def _refusal(path: Path | str) -> str:
    with pytest.raises(ConfigError) as info:
        read_bytes(Path(path), "rig file", error=ConfigError)
    return str(info.value)


def test_reads_a_regular_file(tmp_path):
    f = tmp_path / "rig.toml"
    f.write_bytes(b"a = 1\n")
    assert read_bytes(f, "rig file", error=ConfigError) == b"a = 1\n"


def test_refuses_what_is_not_a_regular_file(tmp_path):
    assert _refusal("/dev/zero") == (
        "/dev/zero: is a device, not a regular file; give the rig file as a file"
    )
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)  # opened non-blocking: no writer, no hang
    assert _refusal(fifo) == f"{fifo}: is a FIFO, not a regular file; give the rig file as a file"
    assert _refusal(tmp_path) == f"{tmp_path}: is a folder, not a rig file"


def test_not_a_file_says_what_read_bytes_would(tmp_path):
    """For a file another reader opens later (cv2.FileStorage, a video): the same words."""
    f = tmp_path / "screen.yml"
    f.write_text("%YAML:1.0\n")
    assert not_a_file(f, "rig file") is None
    assert not_a_file(tmp_path / "absent.yml", "rig file") == "rig file not found"
    link = tmp_path / "link.yml"
    link.symlink_to(tmp_path / "gone.yml")
    assert (
        not_a_file(link, "rig file")
        == f"rig file not found (a symlink to {str(tmp_path / 'gone.yml')!r}, absent)"
    )
    for path in ("/dev/zero", tmp_path):
        assert f"{path}: {not_a_file(path, 'rig file')}" == _refusal(path)


@pytest.mark.parametrize(
    ("loads", "text", "said"),
    [
        (loads_toml, "[a]\nb = [0.5, -1e308]\n", "a.b[1] is -1e+308; numbers in a rig file must "
         "be within +-1e+15"),
        (loads_toml, "n = 123456789012345678901234567890\n", "n is 123456789012345678901234567890, "
         "an integer beyond 64 bits"),
        (loads_toml, "n = " + "9" * 5000 + "\n", "an integer with thousands of digits"),
        (loads_json, '{"a": {"b": 1e300}}', "a.b is 1e+300; numbers in a rig file"),
        (loads_json, "[1e400]", "1e400 overflows a float"),
        (loads_json, "[" + "9" * 5000 + "]", "an integer of 5000 digits is beyond 64 bits"),
    ],
)  # fmt: skip
def test_absurd_numbers_are_refused_naming_the_key(loads, text, said):
    """1e308 passes isfinite and overflows in the first square downstream (fuzz seeds 13, 17);
    a 5000-digit integer made Python's int() raise a bare ValueError."""
    with pytest.raises(ConfigError) as info:
        loads(text, "rig.toml", "rig file", ConfigError)
    assert str(info.value).startswith("rig.toml: ")
    assert said in str(info.value)


def test_numbers_a_file_may_hold_pass():
    text = '{"t_ns": 1796000000000000000, "x": -1e15, "y": 5e-324, "on": true}'
    assert loads_json(text, "rec.jsonl", "pointer event", ConfigError) == {
        "t_ns": 1796000000000000000, "x": -1e15, "y": 5e-324, "on": True
    }  # fmt: skip
    assert loads_toml("a = inf\nb = 9223372036854775807\n", "d.toml", "x")["b"] == (1 << 63) - 1
