"""The plugin registry over real entry points (dist-info folders put on sys.path)."""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import pytest

from omnidev import registry
from omnidev.cli.main import main
from omnidev.errors import PluginError


def make_dist(
    root: Path, name: str, entry_points: str, module: str | None = None, code: str = ""
) -> None:
    """A minimal installed distribution: NAME-1.0.dist-info with METADATA and entry_points.txt."""
    info = root / f"{name.replace('-', '_')}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(textwrap.dedent(entry_points))
    if module:
        (root / f"{module}.py").write_text(textwrap.dedent(code))


@pytest.fixture
def plugin_path(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    registry.refresh()
    yield tmp_path
    for mod in [m for m in sys.modules if m.startswith("fake_")]:
        del sys.modules[mod]
    registry.refresh()


def test_first_party_plugins_are_listed():
    names = {p.name: p for p in registry.plugins("omnidev.unwarpers")}
    assert names["pano-table"].distribution == "omnidev-pano-table"
    assert not names["pano-table"].broken
    sources = {p.name for p in registry.plugins("omnidev.sources")}
    assert {"video", "images", "v4l2", "usb"} <= sources


def test_broken_plugin_is_listed_and_others_work(plugin_path, capsys):
    make_dist(
        plugin_path,
        "fake-broken",
        """
        [omnidev.unwarpers]
        broken-kind = fake_broken:Unwarper
        """,
        "fake_broken",
        "import no_such_module_anywhere\n",
    )
    infos = {p.name: p for p in registry.plugins("omnidev.unwarpers")}
    assert infos["broken-kind"].broken
    assert "no_such_module_anywhere" in (infos["broken-kind"].error or "")
    assert not infos["pano-table"].broken
    assert registry.get("omnidev.unwarpers", "pano-table") is not None
    with pytest.raises(PluginError, match="broken-kind.*fake-broken.*broken"):
        registry.get("omnidev.unwarpers", "broken-kind")
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert "broken-kind" in out and "BROKEN" in out and "omnidev-pano-table 0.1.0" in out


def test_duplicate_names_name_both_distributions(plugin_path):
    for dist in ("fake-one", "fake-two"):
        make_dist(
            plugin_path / dist,
            dist,
            """
            [omnidev.trackers]
            same-name = fake_x:T
            """,
        )
        sys.path.insert(0, str(plugin_path / dist))
    try:
        registry.refresh()
        listed = [p for p in registry.plugins("omnidev.trackers") if p.name == "same-name"]
        assert [p.distribution for p in listed] == ["fake-one", "fake-two"]
        assert all(p.broken and "fake-one and fake-two" in str(p.error) for p in listed)
        with pytest.raises(PluginError, match="same-name.*fake-one and fake-two"):
            registry.get("omnidev.trackers", "same-name")
        # the rest of the group keeps working
        assert registry.get("omnidev.unwarpers", "pano-table") is not None
    finally:
        for dist in ("fake-one", "fake-two"):
            sys.path.remove(str(plugin_path / dist))


def test_unknown_kind_names_installed(plugin_path):
    with pytest.raises(PluginError, match="camera kind 'nope'.*installed: .*pano-table"):
        registry.get("omnidev.unwarpers", "nope")
