"""Frames per second of the replay page with many robots, in headless Chromium.

A synthetic avoidance-like trace (random walks of N discs in a square, cells not recorded)
is turned into a replay page; the page then advances one frame per animation frame for a
few seconds and reports how many frames it drew per second (``window.replay.measureFps``).
Needs Chromium and websocket-client."""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from robofleet.core.trace import Trace
from robofleet.viz.replay import scene_builder
from robofleet.viz.replay.browser import HeadlessChromium
from robofleet.viz.replay.page import write_html


def synthetic_trace(n_robots: int, n_steps: int, seed: int = 0) -> Trace:
    """Random walks of ``n_robots`` discs (radius 0.2 m) in a square sized for them."""
    rng = np.random.default_rng(seed)
    side = float(np.sqrt(n_robots) * 1.5)
    start = rng.uniform(0, side, (n_robots, 2))
    walk = np.cumsum(rng.normal(0, 0.04, (n_steps, n_robots, 2)), axis=0)
    positions = np.concatenate([start[None], start + walk])
    metadata = {"scenario": f"synthetic_{n_robots}", "seed": seed, "n_robots": n_robots, "n_steps": n_steps, "method": "random walk",
                "dt": 0.1, "radius": 0.2, "goals": start.tolist(), "bounds3d": None, "boxes": []}
    return Trace("avoidance", {"positions": positions}, [], metadata, {"success": True})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--robots", type=int, default=10_000)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--seconds", type=float, default=4.0)
    args = ap.parse_args()
    trace = synthetic_trace(args.robots, args.steps)
    started = time.perf_counter()
    scene = scene_builder("avoidance")(trace)
    with tempfile.TemporaryDirectory() as tmp:
        page_path = write_html(scene, Path(tmp) / "replay.html")
        built = time.perf_counter() - started
        with HeadlessChromium(width=1280, height=800) as browser:
            started = time.perf_counter()
            page = browser.open(page_path.resolve().as_uri())
            page.bring_to_front()
            page.wait_for("document.body.dataset.ready === '1'", timeout=120)
            loaded = time.perf_counter() - started
            fps = page.evaluate(f"window.replay.measureFps({args.seconds})", await_promise=True)
            errors = page.errors
        size = page_path.stat().st_size
    print(f"robots: {args.robots}, frames: {scene.n_frames}, page: {size / 1e6:.1f} MB, built in {built:.1f} s, "
          f"loaded in {loaded:.1f} s")
    print(f"replay: {fps:.1f} frames drawn per second (one frame per animation frame, {args.seconds:g} s, 1280×800)")
    if errors:
        print(f"page errors: {errors[:3]}")


if __name__ == "__main__":
    main()
