"""Trace size, saving memory, replay page and Rerun export of large avoidance runs.

Part 1 (``--robots``, ``--steps``): a dense, noisy B-UAVC circle swap (robots of radius
0.2 m, 0.45 m apart on the circle, σ = 0.25 m, so that many robots report empty cells and
deadlocks at every step: hundreds of thousands of events) is simulated once; then

* saving: ``Trace.save`` under ``tracemalloc`` — the peak of memory allocated while
  saving, against the bytes of the arrays it writes (the trace's arrays and the event
  columns); the sizes of ``trace.json`` and ``trace.npz``;
* loading: ``Trace.load`` wall time;
* the replay page: the scene built from the loaded trace and written as
  ``robofleet view`` does, its wall and CPU time and the page's size.

Part 2 (``--rerun-robots``, ``--rerun-steps``; 0 to skip): a run of that many robots is
simulated and saved, then ``robofleet view RUN --rerun RUN.rrd`` runs in a child process
whose peak RSS (``ru_maxrss``) and wall time are reported.

Usage: ``python benchmarks/trace_size.py --robots 2000 --steps 3000 --rerun-robots 20000 --rerun-steps 300``
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

import robofleet
from robofleet.core.trace import Trace
from robofleet.viz.replay import scene_builder
from robofleet.viz.replay.page import write_html

MB = 1e6
VIEW_CHILD = """
import resource, sys, time
from robofleet.cli.main import main
started = time.perf_counter()
try:
    main(["view", sys.argv[1], "--no-open", "--rerun", sys.argv[2], "--overwrite"])
except SystemExit as stop:
    if stop.code:
        raise
print(f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024} {time.perf_counter() - started}")
"""


SPACING, SIGMA = 0.45, 0.25
"""Distance between neighbours on the circle [m] and the estimates' noise [m]."""


def dense_swap(n_robots: int, steps: int):
    """The shipped circle swap with ``n_robots`` robots :data:`SPACING` apart on the circle."""
    radius = n_robots * SPACING / (2 * np.pi)
    bound = radius + 2.0
    return robofleet.load_scenario("avoidance/circle_swap", {"robots.n": n_robots, "max_steps": steps, "robots.layout.radius": radius,
                                                           "robots.sigma": SIGMA, "workspace.bounds": [-bound, -bound, bound, bound]})


def simulated(n_robots: int, steps: int, seed: int) -> tuple[Trace, float]:
    started = time.perf_counter()
    trace = robofleet.simulate(dense_swap(n_robots, steps), seed=seed)
    return trace, time.perf_counter() - started


def measure_save(trace: Trace, directory: Path) -> dict:
    """Peak memory allocated while saving (tracemalloc) against the bytes written."""
    arrays = sum(np.asarray(a).nbytes for a in trace.arrays.values()) + sum(a.nbytes for a in trace.events.to_arrays().values())
    tracemalloc.start()
    tracemalloc.reset_peak()
    started = time.perf_counter()
    trace.save(directory)
    seconds = time.perf_counter() - started
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"arrays_mb": arrays / MB, "save_peak_mb": peak / MB, "peak_over_arrays": peak / arrays, "save_s": seconds,
            "trace_json_mb": (directory / "trace.json").stat().st_size / MB, "trace_npz_mb": (directory / "trace.npz").stat().st_size / MB}


def measure_page(directory: Path) -> dict:
    started = time.perf_counter()
    trace = Trace.load(directory)
    loaded = time.perf_counter() - started
    started, cpu = time.perf_counter(), time.process_time()
    scene = scene_builder(trace.family)(trace)
    page = write_html(scene, directory / "replay.html")
    built, built_cpu = time.perf_counter() - started, time.process_time() - cpu
    return {"load_s": loaded, "page_build_s": built, "page_build_cpu_s": built_cpu, "page_mb": page.stat().st_size / MB,
            "frames": scene.n_frames,
            "page_events": len(scene.events)}


def measure_rerun(directory: Path) -> dict:
    out = subprocess.run([sys.executable, "-c", VIEW_CHILD, str(directory), str(directory / "run.rrd")], capture_output=True, text=True,
                         check=True)
    peak, seconds = out.stdout.split()[-2:]
    return {"view_rerun_peak_rss_mb": int(peak) / MB, "view_rerun_s": float(seconds),
            "rrd_mb": (directory / "run.rrd").stat().st_size / MB}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, default=2000)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--rerun-robots", type=int, default=20_000)
    ap.add_argument("--rerun-steps", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.robots:
            trace, seconds = simulated(args.robots, args.steps, args.seed)
            row = {"robots": args.robots, "steps": trace.metadata["n_steps"], "events": len(trace.events), "simulate_s": seconds}
            row.update(measure_save(trace, Path(tmp) / "run"))
            del trace
            row.update(measure_page(Path(tmp) / "run"))
            print(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in row.items()}), flush=True)
        if args.rerun_robots:
            trace, seconds = simulated(args.rerun_robots, args.rerun_steps, args.seed)
            row = {"robots": args.rerun_robots, "steps": trace.metadata["n_steps"], "events": len(trace.events), "simulate_s": seconds}
            trace.save(Path(tmp) / "big")
            del trace
            row.update(measure_rerun(Path(tmp) / "big"))
            print(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in row.items()}), flush=True)


if __name__ == "__main__":
    main()
