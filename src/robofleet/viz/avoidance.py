"""Figures and animations of the avoidance family (Zhu et al. 2022, B-UAVC; Zhu, Brito &
Alonso-Mora 2022), and the figures of its reproductions.

Reads traces (arrays, metadata, workspace) and result tables only. Every kind of
avoidance trace is drawn by the same two functions, from what the trace recorded:

* 2-D runs (single and double integrators, differential drive): the workspace bounds
  and obstacles, true discs, trails and goals; each robot's cell (B-UAVC, BVC or
  inflated BVC, Sec. 4) when ``cell_A``/``cell_b`` were recorded; 3σ ellipses of the
  position estimates when ``metadata["robot_cov"]`` is given; headings when recorded;
* 3-D runs (quadrotors, mixed ground/air teams): a top view with the height as colour
  and the yawed boxes (``metadata["boxes"]``) as their footprints.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Ellipse, FancyArrow
from matplotlib.patches import Polygon as PolygonPatch

from ..core.trace import Trace
from .avoidance_geometry import (
    TRAIL_STEPS,
    box_clip,
    box_footprint,
    cell_polygon,
    clip_region,
    height_range,
    is_three_d,
    local_box_view,
    uncertainty_ellipse,
    view_extent,
)
from .animation import (
    FrameTitle,
    fit_canvas,
    frame_indices,
    mark_zero_rates,
    outside_legend,
    proxy,
    run_title,
    save_figure,
    save_gif,
    visible_legend,
    workspace_figure,
)

if TYPE_CHECKING:
    import pandas as pd

METHOD_STYLE = {"buavc": ("B-UAVC", "C0", "o"), "bvc": ("BVC", "C1", "s"), "bvc_inflated": ("BVC inflated", "C2", "^"),
                "orca": ("ORCA", "C3", "D")}
"""Label, colour and marker of each method in the reproduction figures."""


# -- traces --------------------------------------------------------------------------
def draw_workspace(ax: plt.Axes, trace: Trace) -> None:
    """Bounds and obstacles (2-D polygons, or 3-D box footprints), limits and aspect."""
    lo, hi = view_extent(trace)
    if trace.workspace is not None and not is_three_d(trace):
        ax.add_patch(PolygonPatch(trace.workspace.bounds, closed=True, fill=False, lw=1.2, color="k"))
        for vertices in trace.workspace.obstacles:
            ax.add_patch(PolygonPatch(vertices, closed=True, color="0.35"))
    else:
        ax.add_patch(PolygonPatch([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]], closed=True, fill=False, lw=1.2, color="k"))
    for box in trace.metadata.get("boxes") or []:
        ax.add_patch(PolygonPatch(box_footprint(box["center"], box["size"], box.get("yaw", 0.0)), closed=True, color="0.35", alpha=0.8))
    pad = 0.03 * float(max(hi - lo))
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")


def robot_palette(n: int) -> np.ndarray:
    """RGBA colour per robot index: tab10's saturated colours for up to 10 robots, tab20 for
    up to 20, evenly spaced hues of turbo beyond."""
    if n <= 10:
        return plt.cm.tab10(np.arange(n))
    if n <= 20:
        return plt.cm.tab20(np.arange(n))
    return plt.cm.turbo(np.linspace(0.05, 0.95, n))


def robot_colours(trace: Trace, k: int | None = None) -> np.ndarray:
    """RGBA colour per robot: by index in 2-D (:func:`robot_palette`); in 3-D by the height
    at state ``k`` (viridis over :func:`height_range`; the start height when ``k`` is ``None``)."""
    n = trace.positions.shape[1]
    if not is_three_d(trace):
        return robot_palette(n)
    norm = plt.Normalize(*height_range(trace))
    return plt.cm.viridis(norm(trace.positions[0 if k is None else k, :, 2]))


def outcome_text(trace: Trace) -> str:
    """``success=..., collisions=...`` from the run's results (what was recorded)."""
    summary = trace.summary()
    keys = [k for k in ("success", "collisions", "obstacle_collisions") if k in summary]
    return ", ".join(f"{k}={summary[k]}" for k in keys)


def plot_trace(trace: Trace, path: str | Path) -> Path:
    """Static figure of a run (:func:`trace_figure`) written to ``path``."""
    return save_figure(trace_figure(trace), path)


def trace_figure(trace: Trace) -> plt.Figure:
    """Static figure of a run: every robot's true path, start (○) and goal (×), one colour
    per robot (:func:`robot_palette`); the canvas sized to the workspace
    (:func:`~.animation.fit_canvas`), the legend beside it.

    3-D runs are drawn from above (the title says so), with the box footprints.
    """
    fig, ax = workspace_figure(*view_extent(trace))
    draw_workspace(ax, trace)
    pos = trace.positions
    goals = np.asarray(trace.metadata["goals"], float)
    colours = robot_palette(pos.shape[1])
    for i in range(pos.shape[1]):
        ax.plot(pos[:, i, 0], pos[:, i, 1], color=colours[i], lw=1)
        ax.plot(*pos[0, i, :2], "o", color=colours[i], ms=4)
        ax.plot(*goals[i, :2], "x", color=colours[i], ms=6)
    ax.set(xlabel="x [m]", ylabel="y [m]")
    ax.set_title(f"{run_title(trace)}\n{outcome_text(trace)}" + (" (top view)" if is_three_d(trace) else ""), fontsize=9)
    handles = [proxy("path (one colour per robot)", color="C0", ls="-"), proxy("start", color="C0", marker="o", ms=5),
               proxy("goal", color="C0", marker="x")]
    if trace.workspace is not None and len(trace.workspace.obstacles) or trace.metadata.get("boxes"):
        handles.append(proxy("obstacle" + (" (footprint)" if is_three_d(trace) else ""), color="0.35", marker="s", ms=9))
    outside_legend(ax, handles)
    return fit_canvas(fig)


# -- cells and uncertainty -------------------------------------------------------------
def heading_arrow(ax: plt.Axes, radius: float) -> FancyArrow:
    """A robot's heading arrow (:func:`point_heading` places it), added to ``ax``."""
    return ax.add_patch(FancyArrow(0.0, 0.0, 1.8 * radius, 0.0, head_width=0.4 * radius, color="k", lw=0.8,
                                   length_includes_head=True))


def point_heading(arrow: FancyArrow, position: np.ndarray, heading: float, radius: float) -> None:
    """``arrow`` of length 1.8 r along ``heading`` from the robot's centre."""
    arrow.set_data(x=position[0], y=position[1], dx=1.8 * radius * np.cos(heading), dy=1.8 * radius * np.sin(heading))


def animate_trace(trace: Trace, path: str | Path, fps: int = 10, max_frames: int = 150) -> Path:
    """GIF of a run (:func:`animation_scene`), at most ``max_frames`` evenly spaced states;
    the workspace, legend and labels are drawn once, each frame blits the robots' artists."""
    fig, update = animation_scene(trace)
    return save_gif(fig, update, frame_indices(len(trace.positions), max_frames), path, fps, blit=True)


def animation_scene(trace: Trace) -> tuple[plt.Figure, Callable[[int], list]]:
    """The figure of a run's animation and the function setting it to state ``k`` (it
    returns the artists it moves, per robot in drawing order): true discs with trails and
    goals; each robot's cell when recorded, in the robot's colour, within its local box
    (:func:`local_box_view`), while the robot has not arrived; 3σ ellipses of its estimate
    when ``robot_cov`` is known, headings when recorded; 3-D runs from above with the
    height as colour. The canvas is fitted to the first state's drawing
    (:func:`~.animation.fit_canvas`), the legend beside the workspace."""
    pos = trace.positions
    radius = float(trace.metadata["radius"])
    dt = float(trace.metadata["dt"])
    goals = np.asarray(trace.metadata["goals"], float)
    estimates = trace.arrays.get("estimates")
    has_estimates = estimates is not None and len(estimates) > 0
    headings = trace.arrays.get("headings")
    cells = (trace.arrays["cell_A"], trace.arrays["cell_b"]) if "cell_A" in trace.arrays and "cell_b" in trace.arrays else None
    cov = trace.metadata.get("robot_cov")
    ellipse = uncertainty_ellipse(cov, 3.0) if cov is not None and not is_three_d(trace) else None
    clip = clip_region(trace)
    local_box = local_box_view(trace)
    arrival = np.asarray(trace.arrays.get("arrival_steps", np.full(pos.shape[1], -1)))
    fig, ax = workspace_figure(*view_extent(trace))
    if is_three_d(trace):
        mappable = plt.cm.ScalarMappable(norm=plt.Normalize(*height_range(trace)), cmap="viridis")
        fig.colorbar(mappable, ax=ax, label="height z [m]", location="bottom", shrink=0.8, pad=0.12, aspect=40)  # the legend is on the right
    draw_workspace(ax, trace)
    ax.set(xlabel="x [m]", ylabel="y [m]")
    outside_legend(ax, animation_legend(trace, cells is not None, ellipse is not None, headings is not None, local_box is not None))
    title = FrameTitle(ax, run_title(trace) + (" (top view)" if is_three_d(trace) else ""))
    robots = [RobotArtists.add(ax, goals[i], radius, cells is not None, ellipse, headings is not None) for i in range(pos.shape[1])]

    def update(k: int) -> list:
        colours = robot_colours(trace, k) if is_three_d(trace) else robot_colours(trace)
        trail = pos[max(0, k - TRAIL_STEPS): k + 1]
        for i, robot in enumerate(robots):
            robot.colour(colours[i])
            if robot.cell is not None:
                robot.cell.set_visible(False)  # an arrived robot's cell only hides the others
                if len(cells[0]) and not 0 <= arrival[i] <= k:
                    step = min(k, len(cells[0]) - 1)
                    centre = estimates[min(step, len(estimates) - 1), i, :2] if has_estimates else pos[k, i, :2]
                    robot.shape_cell(cells[0][step, i], cells[1][step, i], clip, centre, local_box)
            robot.trail.set_data(trail[:, i, 0], trail[:, i, 1])
            robot.disc.set_center(pos[k, i, :2])
            if robot.ellipse is not None:
                robot.ellipse.set_visible(has_estimates)
                if has_estimates:
                    robot.ellipse.set_center(estimates[min(k, len(estimates) - 1), i, :2])
            if robot.heading is not None:
                robot.heading.set_visible(bool(np.isfinite(headings[k, i])))
                if np.isfinite(headings[k, i]):
                    point_heading(robot.heading, pos[k, i], float(headings[k, i]), radius)
        return [artist for robot in robots for artist in robot.in_drawing_order()] + [title.show(f"t = {k * dt:.1f} s")]

    update(0)
    fit_canvas(fig)
    return fig, update


@dataclass
class RobotArtists:
    """What a robot's animation frame shows, each artist made once and moved per frame."""

    cell: PolygonPatch | None
    trail: Line2D
    disc: Circle
    ellipse: Ellipse | None
    heading: FancyArrow | None
    goal: Line2D

    @classmethod
    def add(cls, ax: plt.Axes, goal: np.ndarray, radius: float, cell: bool, ellipse: tuple | None, heading: bool) -> "RobotArtists":
        """The artists of one robot, added to ``ax`` in its drawing order (cell, trail,
        disc, ellipse, heading, goal): a cell with a light fill and a solid edge, the
        trail, the true disc, the dashed 3σ ellipse, the heading arrow, the goal ×."""
        return cls(
            ax.add_patch(PolygonPatch(np.zeros((3, 2)), closed=True, lw=0.8)) if cell else None,
            ax.plot([], [], lw=0.6, alpha=0.6)[0],
            ax.add_patch(Circle((0.0, 0.0), radius, alpha=0.85)),
            ax.add_patch(Ellipse((0.0, 0.0), ellipse[0], ellipse[1], angle=ellipse[2], fill=False, ls="--", lw=0.6))
            if ellipse is not None else None,
            heading_arrow(ax, radius) if heading else None,
            ax.plot(*goal[:2], "x")[0],
        )

    def in_drawing_order(self) -> list:
        return [a for a in (self.cell, self.trail, self.disc, self.ellipse, self.heading, self.goal) if a is not None]

    def colour(self, colour: Any) -> None:
        """Every artist of the robot in ``colour`` (the heading stays black)."""
        if self.cell is not None:
            self.cell.set_facecolor((*colour[:3], CELL_ALPHA))
            self.cell.set_edgecolor(colour)
        self.trail.set_color(colour)
        self.disc.set_color(colour)
        if self.ellipse is not None:
            self.ellipse.set_edgecolor(colour)
        self.goal.set_color(colour)

    def shape_cell(self, A: np.ndarray, b: np.ndarray, clip: np.ndarray, centre: np.ndarray, local_box: float | None) -> None:
        """The cell ``{p : A p ≤ b}`` inside ``clip``, cut to its local box ``centre ±
        local_box`` when given; hidden when that leaves less than a triangle."""
        polygon = cell_polygon(A, b, clip)
        if local_box is not None and len(polygon) >= 3:
            polygon = box_clip(polygon, centre, local_box)
        self.cell.set_visible(len(polygon) >= 3)
        if len(polygon) >= 3:
            self.cell.set_xy(polygon)


CELL_ALPHA = 0.18
"""Opacity of a cell's fill (its edge is opaque)."""


def animation_legend(trace: Trace, cells: bool, ellipses: bool, headings: bool, local_box: bool = False) -> list:
    """Legend entries of what :func:`animate_trace` draws for this trace."""
    colour = "C0"
    handles = [proxy("robot (true position)" + (", colour = height" if is_three_d(trace) else ""), color=colour, marker="o", ms=9),
               proxy(f"trail (last {TRAIL_STEPS} steps)", color=colour, ls="-", lw=0.8), proxy("goal", color=colour, marker="x")]
    if cells:
        method = METHOD_STYLE.get(str(trace.metadata.get("method")), ("B-UAVC",))[0]
        where = "\nwithin its local box (±R_loc)" if local_box else ""
        handles.append(proxy(f"{method} cell of a robot not arrived{where}", color=colour, marker="s", ms=10,
                             mfc=(*matplotlib.colors.to_rgb(colour), CELL_ALPHA)))
    if ellipses:
        handles.append(proxy("3σ ellipse of the estimate", color=colour, ls="--", lw=0.8))
    if headings:
        handles.append(proxy("heading", color="k", ls="-", lw=0.8))
    if trace.workspace is not None and len(trace.workspace.obstacles) or trace.metadata.get("boxes"):
        handles.append(proxy("obstacle", color="0.35", marker="s", ms=10))
    return handles


# -- reproduction figures -----------------------------------------------------------------
def plot_buavc_comparison(noise: pd.DataFrame, delta: pd.DataFrame, path: str | Path) -> Path:
    """Four panels of ``robofleet reproduce buavc``: runs with a collision, success rate and
    travel time against σ per method, and B-UAVC's pooled per-pair-per-step collision
    rate (with its 95 % upper bound) against δ and the bound y = δ of Eq. (12).

    ``noise`` has columns ``method, sigma, run_collided, success, mean_travel_time``;
    ``delta`` has ``delta, pair_step_pooled, pair_step_upper``.
    """
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    for method, group in noise.groupby("method"):
        label, colour, marker = METHOD_STYLE.get(method, (method, "k", "x"))
        group = group.sort_values("sigma")
        for ax, column in zip(axes[:3], ("run_collided", "success", "mean_travel_time")):
            ax.plot(group["sigma"], group[column], marker=marker, color=colour, label=label)
    axes[0].set(xlabel="σ [m]", ylabel="runs with a collision", title="collisions vs noise")
    axes[1].set(xlabel="σ [m]", ylabel="success rate", title="success vs noise")
    axes[2].set(xlabel="σ [m]", ylabel="mean travel time [s]", title="travel time vs noise")
    d = delta["delta"].to_numpy(float)
    pooled = delta["pair_step_pooled"].to_numpy(float)
    upper = delta["pair_step_upper"].to_numpy(float)
    seen = pooled > 0
    axes[3].loglog(d[seen], pooled[seen], "o", color="C0", label="B-UAVC, observed per pair and step")
    axes[3].loglog(d[seen], upper[seen], "_", color="C0", ms=12, mew=1.5, label="95 % upper bound of an observed rate")
    mark_zero_rates(axes[3], d[~seen], upper[~seen])
    axes[3].loglog(d, d, "k--", label="bound δ")
    axes[3].set(xlabel="δ (risk threshold per pair and step)", ylabel="collision probability per pair and step",
                title="chance constraint (Eq. 12)")
    visible_legend(axes[3], fontsize=7)
    visible_legend(axes[0])
    runs = f" · {int(noise['runs'].max())} runs per point" if "runs" in noise and len(noise) else ""
    fig.suptitle(f"reproduce buavc: B-UAVC, BVC and inflated BVC, circle swaps{runs}", fontsize=10)
    return save_figure(fig, path, tight=True)


def plot_models_noise(noise: pd.DataFrame, path: str | Path) -> Path:
    """``robofleet reproduce buavc-models``: per robot model (columns), the share of runs
    with a collision (top) and the success rate (bottom) against σ, one line per method.

    ``noise`` has columns ``model, method, sigma, run_collided, success``.
    """
    models = list(dict.fromkeys(noise["model"]))
    fig, axes = plt.subplots(2, max(1, len(models)), figsize=(3.2 * max(1, len(models)), 5.6), squeeze=False)
    for col, model in enumerate(models):
        for method, group in noise[noise["model"] == model].groupby("method"):
            label, colour, marker = METHOD_STYLE.get(method, (method, "k", "x"))
            group = group.sort_values("sigma")
            axes[0, col].plot(group["sigma"], 100 * group["run_collided"].astype(float), marker=marker, color=colour, label=label)
            axes[1, col].plot(group["sigma"], 100 * group["success"].astype(float), marker=marker, color=colour, label=label)
        axes[0, col].set_title(model.replace("_", " "))
        axes[1, col].set_xlabel("σ [m]")
    for ax in axes.ravel():
        ax.set_ylim(-5, 105)
    axes[0, 0].set_ylabel("runs with a collision [%]")
    axes[1, 0].set_ylabel("success [%]")
    if models:
        axes[0, 0].legend(fontsize=7)
    return save_figure(fig, path, tight=True)


def plot_models_delta(delta: pd.DataFrame, path: str | Path) -> Path:
    """``robofleet reproduce buavc-models``: B-UAVC's mean per-step pair collision rate
    against δ per model, with the bound y = δ. A rate of 0 is not drawn at an invented
    floor: it is marked ``0 observed`` at its 95 % upper bound when the table has
    ``pair_step_upper``, else on the lower edge of the axes.

    ``delta`` has columns ``model, delta, pair_step_rate`` (and optionally ``pair_step_upper``).
    """
    fig, ax = plt.subplots(figsize=(5.6, 3.8))
    for k, (model, group) in enumerate(delta.groupby("model")):
        group = group.sort_values("delta")
        rate = group["pair_step_rate"].to_numpy(float)
        seen = rate > 0
        ax.plot(group["delta"].to_numpy(float)[seen], rate[seen], marker="o", color=f"C{k}", label=model.replace("_", " "))
        upper = group["pair_step_upper"].to_numpy(float)[~seen] if "pair_step_upper" in group else None
        mark_zero_rates(ax, group["delta"].to_numpy(float)[~seen], upper, color=f"C{k}")
    d = np.array(sorted(delta["delta"].unique()), float)
    ax.plot(d, d, "k--", label="bound δ")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set(xlabel="δ (risk threshold per pair and step)", ylabel="pair collision rate per step",
           title="reproduce buavc-models: chance constraint, B-UAVC")
    visible_legend(ax, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return save_figure(fig, path, tight=True)
