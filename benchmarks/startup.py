"""Wall time of the commands that should answer at once, and of a first and second run.

Each command runs as a new process (``python -m robofleet ...``, what the ``robofleet``
script does) ``--repeat`` times; the table gives the median and the fastest run. Then a
small run (``--run``) is timed twice in a fresh numba cache folder: the first run compiles
the kernels it needs, the second loads them from the cache and compiles nothing.

    python benchmarks/startup.py [--repeat 7] [--run avoidance/circle_swap]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _machine import machine

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = (
    ["--version"],
    ["--help"],
    ["scenarios"],
    ["validate", "scenarios/avoidance/circle_swap.yaml"],
    ["validate", "scenarios/coordination/x_corridor_5_tff.yaml"],
    ["validate", "scenarios/flocking/wedge_async.yaml"],
    ["validate", "scenarios/search/fig7.yaml"],
)


def wall_time(args: list[str], env: dict[str, str] | None = None) -> float:
    """Seconds from starting ``python -m robofleet ARGS`` to its exit (which must be 0)."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "robofleet", *args], cwd=ROOT, env=env, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"robofleet {' '.join(args)} failed ({proc.returncode}): {proc.stderr.strip()[-500:]}")
    return elapsed


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="runs of each command (median and best are shown)")
    ap.add_argument("--run", default="avoidance/circle_swap", help="the scenario run twice in a fresh numba cache")
    args = ap.parse_args()
    print(machine())
    print(f"{'command':<66} {'median s':>9} {'best s':>8}")
    for command in COMMANDS:
        times = [wall_time(command) for _ in range(args.repeat)]
        print(f"{'robofleet ' + ' '.join(command):<66} {statistics.median(times):>9.3f} {min(times):>8.3f}")
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        run = ["run", args.run, "--seed", "1", "--quiet", "--overwrite", "--out", out]
        first, second = wall_time(run, env), wall_time(run, env)
        print(f"{'robofleet run ' + args.run + ' (fresh numba cache)':<66} {first:>9.3f}")
        print(f"{'robofleet run ' + args.run + ' (same cache, second run)':<66} {second:>9.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
