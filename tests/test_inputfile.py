"""omnidev.inputfile's safe reader: what it refuses, and the one line it says for each."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from omnidev.errors import ConfigError
from omnidev.inputfile import read_bytes


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
