"""Run the fuzz suite outside pytest and print every failing case and the counts by command.

python -m tests.fuzz.run                 # the cases of the normal test run
python -m tests.fuzz.run --random 200    # plus 200 random mutations per file format
python -m tests.fuzz.run --only unwarp   # commands containing 'unwarp'
python -m tests.fuzz.run --workers 2 --json out.json
"""

from __future__ import annotations

import argparse
import json
import os
import random
import sys
import tempfile
import time
from pathlib import Path

from tests.fuzz.harness import GOOD, Case, ServerPool, run_cases, summary
from tests.fuzz.mutate import NUMBER
from tests.fuzz.seeds import make_seeds
from tests.fuzz.targets import (
    FILE_TARGETS,
    config_key_cases,
    file_cases,
    option_cases,
    seed_cases,
)


def random_cases(seeds, per_target: int, seed: int) -> list[Case]:
    """Random edits of each seed (the same edit kinds as test_random_mutations)."""
    from tests.fuzz.test_fuzz import _TOKENS

    rng = random.Random(seed)
    out = []
    for t in FILE_TARGETS:
        base = seeds.text(t.seed)
        for _ in range(per_target):
            blob = base
            for _ in range(rng.randint(1, 4)):
                how = rng.choice(["token", "cut", "repeat", "byte"])
                numbers = list(NUMBER.finditer(blob))
                if how == "token" and numbers:
                    m = rng.choice(numbers)
                    blob = blob[: m.start()] + rng.choice(_TOKENS) + blob[m.end() :]
                elif how == "cut" and blob:
                    i = rng.randrange(len(blob))
                    blob = blob[:i] + blob[i + rng.randint(0, 64) :]
                elif how == "repeat" and blob:
                    i = rng.randrange(len(blob))
                    blob = blob[:i] + blob[i : i + 32] * rng.randint(2, 50) + blob[i:]
                elif blob:
                    i = rng.randrange(len(blob))
                    blob = blob[:i] + bytes([rng.randrange(256)]) + blob[i + 1 :]
            argv = [a.replace("{f}", t.file_name).replace("{s}", str(seeds.root)) for a in t.argv]
            files = {t.file_name: blob}
            if t.seed == "rig.toml":
                files.update({"cam.yml.gz": seeds.text("cam.yml.gz"),
                              "omni.png": seeds.text("omni.png")})  # fmt: skip
            out.append(Case(t.command, f"{t.what}: random edits", argv, files, expect="any"))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--random", type=int, default=0, help="random mutations per file format")
    ap.add_argument("--seed", type=int, default=1, help="seed of the random mutations")
    ap.add_argument("--only", help="run only commands containing this text")
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--json", type=Path, help="write every outcome here")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="omnidev-fuzz-") as d:
        os.chmod(d, 0o755)
        work = Path(d)
        seeds = make_seeds(work / "seeds")
        plain = seed_cases(seeds)
        cases = [*plain, *file_cases(seeds), *option_cases(seeds), *config_key_cases(seeds)]
        cases += random_cases(seeds, args.random, args.seed)
        if args.only:
            cases = [c for c in cases if args.only in c.command]
        t0 = time.monotonic()
        with ServerPool(args.workers) as pool:
            outcomes = run_cases(pool, cases, work / "run")
        took = time.monotonic() - t0
    plain_whats = {(c.command, c.what) for c in plain}
    refused = [
        o for o in outcomes if (o.case.command, o.case.what) in plain_whats and o.cls != "accepted"
    ]
    bad = [o for o in outcomes if o.cls not in GOOD]
    for o in refused:
        print("SEED REFUSED (fuzzing this input would be vacuous): " + o.describe())
    for o in bad:
        print(o.describe())
    bad += refused
    print(summary(outcomes))
    print(f"{len(outcomes)} cases in {took:.0f} s with {args.workers} workers; {len(bad)} bad")
    if args.json:
        args.json.write_text(json.dumps([
            {"command": o.case.command, "what": o.case.what, "argv": list(o.case.argv),
             "class": o.cls, "rc": o.rc, "seconds": o.seconds, "maxrss_kb": o.maxrss_kb,
             "stderr": o.stderr[-2000:]} for o in outcomes], indent=1))  # fmt: skip
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
