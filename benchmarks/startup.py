"""Wall time of the commands that should answer at once, and of a first and second run.

Each command runs as a new process (``python -m robofleet ...``, what the ``robofleet``
script does) ``--repeat`` times; the table gives the median and the fastest wall time, and
the median CPU time (user + system, which other jobs on the machine disturb less). Then a
small run (``--run``, ``--run ''`` for none) is timed twice in a fresh numba cache folder:
the first run compiles the kernels it needs, the second loads them from the cache and
compiles nothing. The machine line gives the load average before, the last line after.

    python benchmarks/startup.py [--repeat 7] [--run avoidance/circle_swap]
"""

from __future__ import annotations

import argparse
import os
import resource
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
    ["validate", "scenarios/avoidance/quadrotors_3d.yaml"],
    ["validate", "scenarios/avoidance/diff_drive.yaml"],
    ["validate", "scenarios/coordination/x_corridor_5_tff.yaml"],
    ["validate", "scenarios/flocking/wedge_async.yaml"],
    ["validate", "scenarios/search/fig7.yaml"],
)


def timed(args: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall and CPU seconds of ``python -m robofleet ARGS`` (which must exit with 0)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "robofleet", *args], cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"robofleet {' '.join(args)} failed ({proc.returncode}): {proc.stderr.strip()[-500:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="runs of each command (median and best are shown)")
    ap.add_argument("--run", default="avoidance/circle_swap", help="the scenario run twice in a fresh numba cache ('' for none)")
    args = ap.parse_args()
    print(machine())
    print(f"{'command':<66} {'wall median s':>13} {'wall best s':>11} {'CPU median s':>12}")
    for command in COMMANDS:
        walls, cpus = zip(*(timed(command) for _ in range(args.repeat)))
        print(f"{'robofleet ' + ' '.join(command):<66} {statistics.median(walls):>13.3f} {min(walls):>11.3f} {statistics.median(cpus):>12.3f}")
    if args.run:
        with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
            env = {**os.environ, "NUMBA_CACHE_DIR": cache}
            run = ["run", args.run, "--seed", "1", "--quiet", "--overwrite", "--out", out]
            for label in ("fresh numba cache", "same cache, second run"):
                wall, cpu = timed(run, env)
                print(f"{'robofleet run ' + args.run + ' (' + label + ')':<66} {wall:>13.3f} {'':>11} {cpu:>12.3f}")
    print("load average after: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
