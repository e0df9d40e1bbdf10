"""Regenerate the gallery of docs/gallery.md: one replay screenshot per family (headless
Chromium) and the flocking and search figures. Run from the repository root:

    .venv/bin/python docs/make_gallery.py
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import robofleet
from robofleet.scenarios import FAMILIES
from robofleet.viz import flocking as flocking_figures
from robofleet.viz import search as search_figures
from robofleet.viz.replay import scene_builder
from robofleet.viz.replay.browser import screenshot_page
from robofleet.viz.replay.page import write_html

OUT = Path(__file__).resolve().parent / "gallery"
REPLAYS = {  # family: (scenario, seed, frame shown (None: the last))
    "avoidance": ("avoidance/circle_swap", 1, 150),
    "avoidance_3d": ("avoidance/quadrotors_3d", 1, 60),
    "coordination": ("coordination/x_corridor_20", 1, 300),
    "flocking": ("flocking/wedge_async", 1, 700),
    "search": ("search/failure_injection", 1, 40),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name, (scenario, seed, frame) in REPLAYS.items():
            trace = robofleet.simulate(robofleet.load_scenario(scenario), seed=seed)
            page = write_html(scene_builder(trace.family)(trace), Path(tmp) / f"{name}.html")
            print(screenshot_page(page, args.out / f"replay_{name}.png", frame=frame))
            if trace.family == "flocking":
                print(flocking_figures.plot_trace(trace, args.out / "flocking_wedge_async.png"))
                print(flocking_figures.animate_trace(trace, args.out / "flocking_wedge_async.gif", max_frames=60))
            if trace.family == "search":
                print(search_figures.plot_trace(trace, args.out / "search_failure_injection.png"))
                print(search_figures.animate_trace(trace, args.out / "search_failure_injection.gif", max_frames=60))
    assert set(FAMILIES) <= {n.split("_")[0] for n in REPLAYS}


if __name__ == "__main__":
    main()
