"""The episode record of :mod:`robofleet.envs` and its figures, drawn with the avoidance
family's figure code (:mod:`robofleet.viz.avoidance`): an episode becomes a
:class:`~robofleet.core.trace.Trace` with the arrays and metadata that family's traces
carry, so ``plot_trace`` and ``animate_trace`` draw it like a simulated run, and
:func:`frame` draws its last state as an RGB array (``render_mode="rgb_array"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle
from matplotlib.patches import Polygon as PolygonPatch

from ..avoidance.metrics import ControllerCounts, run_results
from ..core.trace import Trace
from ..viz.avoidance import cell_polygon, clip_region, draw_workspace, robot_colours
from .fleet import Fleet, StepOutcome

FRAME_INCHES, FRAME_DPI = 5.0, 96


@dataclass
class EpisodeLog:
    """Per-step rows of one episode (true positions include the initial state)."""

    positions: list[np.ndarray]
    estimates: list[np.ndarray] = field(default_factory=list)
    controls: list[np.ndarray] = field(default_factory=list)
    inside: list[np.ndarray] = field(default_factory=list)
    empty: list[np.ndarray] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    cells: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    arrival: np.ndarray | None = None

    @classmethod
    def start(cls, fleet: Fleet) -> EpisodeLog:
        return cls([fleet.positions.copy()], arrival=np.full(fleet.n, -1, np.int64))

    def record(self, fleet: Fleet, outcome: StepOutcome, seconds: float, step: int, with_cells: bool) -> None:
        """Append one step: the estimates it was decided on, the TRUE positions after it."""
        self.estimates.append(outcome.estimates.copy())
        self.positions.append(fleet.positions.copy())
        self.controls.append(outcome.velocity.copy())
        self.inside.append(outcome.estimate_in_cell.copy())
        self.empty.append(outcome.empty_cell.copy())
        self.seconds.append(seconds)
        self.arrival[(self.arrival < 0) & fleet.arrived] = step
        if with_cells and outcome.result is not None:
            self.cells.append((outcome.result.cells.A.copy(), outcome.result.cells.b.copy()))

    def last_cells(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.cells[-1] if self.cells else None

    def trace(self, fleet: Fleet, seed: int | None, method: str) -> Trace:
        """The episode as an avoidance :class:`Trace` with the family's per-run results."""
        spec = fleet.spec
        positions = np.stack(self.positions)
        arrays = {"positions": positions, "estimates": stack(self.estimates, (fleet.n, 2)), "controls": stack(self.controls, (fleet.n, 2)),
                  "step_seconds": np.asarray(self.seconds, float), "arrival_steps": self.arrival.copy(),
                  "estimate_in_cell": stack(self.inside, (fleet.n,), bool), "empty_cell": stack(self.empty, (fleet.n,), bool)}
        if self.cells:
            arrays["cell_A"], arrays["cell_b"] = padded_cells(self.cells)
        premise = (arrays["estimate_in_cell"], arrays["empty_cell"]) if fleet.safety_filter is not None else None
        results = run_results(positions, fleet.goals, radius=fleet.radius, dt=spec.dt, goal_tolerance=spec.goal_tolerance,
                              workspace=fleet.workspace, boxes=None, step_seconds=arrays["step_seconds"], arrivals=self.arrival,
                              counts=ControllerCounts(empty_cell_steps=int(arrays["empty_cell"].sum())), premise=premise)
        results["max_true_goal_distance"] = float(np.linalg.norm(positions[-1] - fleet.goals, axis=1).max())
        metadata = {**fleet.world.metadata(), "method": f"env, safety {method}", "scenario": spec.scenario_name, "seed": seed,
                    "n_robots": fleet.n, "n_steps": len(positions) - 1, "wall_seconds": float(np.sum(self.seconds))}
        return Trace("avoidance", arrays, [], metadata, results, fleet.workspace)


def current_state(fleet: Fleet, step: int) -> Trace:
    """A one-frame :class:`Trace` of the fleet now (what :func:`frame` draws), without the
    per-run results a whole-episode trace computes."""
    metadata = {**fleet.world.metadata(), "scenario": fleet.spec.scenario_name, "n_steps": step}
    return Trace("avoidance", {"positions": fleet.positions[None].copy()}, [], metadata, {}, fleet.workspace)


def stack(rows: list[np.ndarray], shape: tuple[int, ...], dtype=float) -> np.ndarray:
    """``rows`` stacked, or an empty ``(0, *shape)`` array before the first step."""
    return np.stack(rows).astype(dtype) if rows else np.zeros((0, *shape), dtype)


def padded_cells(log: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Per-step cells ``(T, N, M, 2)`` / ``(T, N, M)``, padded with always-true rows ``0·p ≤ 1``."""
    m = max(a.shape[1] for a, _ in log)
    n = log[0][0].shape[0]
    A, b = np.zeros((len(log), n, m, 2)), np.ones((len(log), n, m))
    for k, (a_k, b_k) in enumerate(log):
        A[k, :, : a_k.shape[1]], b[k, :, : b_k.shape[1]] = a_k, b_k
    return A, b


def frame(trace: Trace, cells: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """The last state of ``trace`` (``metadata["n_steps"]`` steps in) as an ``(H, W, 3)``
    uint8 image: workspace and obstacles, each robot's cell (when given), disc and goal."""
    fig = Figure(figsize=(FRAME_INCHES, FRAME_INCHES), dpi=FRAME_DPI)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    draw_workspace(ax, trace)
    positions, goals = trace.positions[-1], np.asarray(trace.metadata["goals"], float)
    colours, radius, clip = robot_colours(trace), float(trace.metadata["radius"]), clip_region(trace)
    for i, p in enumerate(positions):
        if cells is not None:
            polygon = cell_polygon(cells[0][i], cells[1][i], clip)
            if len(polygon) >= 3:
                ax.add_patch(PolygonPatch(polygon, closed=True, fc=colours[i], alpha=0.15, ec=colours[i], lw=0.6))
        ax.add_patch(Circle(p[:2], radius, color=colours[i], alpha=0.85))
        ax.plot(*goals[i, :2], "x", color=colours[i])
    ax.set_title(f"{trace.scenario}  t = {int(trace.metadata['n_steps']) * float(trace.metadata['dt']):.1f} s", fontsize=9)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
