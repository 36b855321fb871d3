"""``omnidev plugins``: every registered plugin by group, with its distribution and version."""

from __future__ import annotations

import argparse
from typing import Any

from omnidev import registry


def register(sub: Any) -> None:
    p = sub.add_parser("plugins", help="list registered plugins by group")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    for group in registry.GROUPS:
        print(f"{group}:")
        infos = registry.plugins(group)
        if not infos:
            print("  (none installed)")
        for info in infos:
            where = f"{info.distribution} {info.version}"
            if info.broken:
                print(f"  {info.name:<16} {where:<32} BROKEN: {info.error}")
            else:
                print(f"  {info.name:<16} {where}")
    return 0
