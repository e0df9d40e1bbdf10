"""The closed loop of Zhu et al. 2022 for every robot model and team: spec → world → steps → Trace.

Each step the loop draws the estimates and the obstacles' estimated displacements
(:class:`~.world.World`), lets the world decide every input (cells, navigation, the
cell-keeping controllers: :mod:`.world`, :mod:`.cell_model`, :mod:`.navigation`), moves the
TRUE states and records the step; collisions are judged on true positions
(:mod:`~robofleet.avoidance.metrics`). Nothing else lives here.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ..core.family import expect_spec
from ..core.recorder import Recorder
from ..core.rng import as_generator, resolve_seed
from ..core.trace import Trace
from .kernels import run_buffers
from .metrics import RunTally
from .spec import Spec
from .navigation.pipeline import MPC_NO_MPC
from .world import World

RECORD_CELLS_MAX_ROBOTS = 64
"""Cells are recorded by default for fleets up to this size (``record_cells`` overrides)."""


# ---------------------------------------------------------------------------------------
# the loop
# ---------------------------------------------------------------------------------------
def records_cells(spec: Spec, world: World) -> bool:
    """Whether the run records every robot's cell (2-D runs with cells; default N ≤ 64)."""
    if world.cell_model is None or world.dim != 2:
        return False
    return spec.record_cells if spec.record_cells is not None else world.n <= RECORD_CELLS_MAX_ROBOTS


def record_cell_log(rec: Recorder, log: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """Write the per-step cells into ``cell_A (T, N, M, 2)`` / ``cell_b (T, N, M)``, padded
    to the widest step with always-true rows ``0·p ≤ 1``."""
    m = max(a.shape[1] for a, _ in log)
    n, d = log[0][0].shape[0], log[0][0].shape[2]
    rec.step("cell_A", (n, m, d), fill=0.0)
    rec.step("cell_b", (n, m), fill=1.0)
    for k, (a_k, b_k) in enumerate(log):
        rec["cell_A"][k, :, : a_k.shape[1]] = a_k
        rec["cell_b"][k, :, : b_k.shape[1]] = b_k


def simulate(spec: Spec, seed: int | None = None, progress: bool = False) -> Trace:
    """Simulate a scenario and return its :class:`~robofleet.core.trace.Trace`.

    Parameters
    ----------
    spec:
        The validated scenario.
    seed:
        ``None`` draws a fresh seed (recorded as ``trace.seed``); every random draw of the
        run (random layouts, the robots' and obstacles' estimation noise) comes from it,
        so ``simulate(spec, seed=trace.seed)`` replays every array bit for bit.
    progress:
        Show a progress bar.

    Returns
    -------
    Trace
        Arrays ``positions (T+1, N, d)`` true positions, ``estimates (T, N, d)``,
        ``controls (T, N, w)`` (zero-padded to the widest team's inputs), ``headings
        (T+1, N)`` when a team has headings (NaN for the others), ``step_seconds (T,)``
        (cells + controllers of the whole fleet), ``arrival_steps (N,)``, the boolean
        ``estimate_in_cell (T, N)`` (the estimate lay in the robot's own cell when it was
        built, before the controller: the premise of the chance constraint) and
        ``empty_cell (T, N)`` (the cell was empty; both all-False for ORCA, which builds
        no cells); 2-D runs with
        cells record ``cell_A``/``cell_b`` (default for N ≤ 64); runs with an MPC team record
        ``mpc_status (T, N)`` int8 (0 solved, 1 fallback, 2 arrived and holding, −1 no MPC). Events ``arrived``,
        ``deadlock``, ``empty_cell``. Results: :data:`~robofleet.avoidance.metrics.RESULTS`,
        judged on every step (:class:`~robofleet.avoidance.metrics.RunTally`) even when the
        spec's ``record_every`` k > 1 keeps only the rows of steps 0, k, 2k, … (the run is
        the same whatever k). Metadata
        ``loop_seconds``: the step loop's wall time alone, from the first step to the last
        (without the set-up, the recorder's declaring of its arrays included, and without
        the per-run results).
    """
    expect_spec(spec, Spec, "avoidance")  # input validation: a validated avoidance scenario
    seed = resolve_seed(seed)
    rng = as_generator(seed)
    world = World(spec, rng)
    rec = Recorder(spec.max_steps, world.n, label=f"{spec.method} · {world.n} robots", progress=progress, record_every=spec.record_every)
    workspace = spec.workspace.build() if spec.space3d is None else None
    tally = RunTally(spec.robots.radius, workspace, spec.space3d.box_arrays() if spec.space3d is not None else None)
    rec.state("positions", (world.n, world.dim), initial=world.positions(), watch=tally.add_state)  # results judge every step
    if world.has_headings:
        rec.state("headings", (world.n,), initial=world.headings())
    rec.step("estimates", (world.n, world.dim))
    rec.step("controls", (world.n, world.control_width))
    rec.step("estimate_in_cell", (world.n,), dtype=bool, fill=False)
    rec.step("empty_cell", (world.n,), dtype=bool, fill=False)
    cell_log: list | None = [] if records_cells(spec, world) else None
    if world.has_mpc:
        rec.step("mpc_status", (world.n,), dtype=np.int8, fill=MPC_NO_MPC)

    def step(k: int) -> bool:
        estimates = world.estimates(rng)
        shift = world.obstacle_shift(rng)
        with rec.timed(k):
            cells, controls, flags = world.decide(estimates, shift)
        flags = world.measure_premise(cells, estimates, flags)
        world.advance(controls)
        rec.put(k, estimates=estimates, controls=controls, estimate_in_cell=flags.estimate_in_cell, empty_cell=flags.cell_empty)
        tally.add_step(flags.estimate_in_cell, flags.cell_empty, rec.arrival_steps < 0)  # before arrive(k + 1): robots not yet arrived
        if world.has_mpc:
            rec.put(k, mpc_status=world.mpc_status)
        rec.put_state(k + 1, positions=world.positions())
        if world.has_headings:
            rec.put_state(k + 1, headings=world.headings())
        rec.arrive(k + 1, world.arrived())
        rec.events_for(k, "deadlock", flags.deadlocked)
        rec.events_for(k, "empty_cell", flags.empty)
        if cell_log is not None and rec.records(k):
            cell_log.append((cells.A, cells.b))
        return rec.all_arrived and bool(world.home().all())

    started, tallied = time.perf_counter(), tally.seconds
    with run_buffers():  # the steps reuse their large arrays (cells, neighbour tables)
        rec.run(step)
    loop_seconds = time.perf_counter() - started - (tally.seconds - tallied)  # the steps, without tallying the per-run results
    if cell_log:
        record_cell_log(rec, cell_log)
    arrays = rec.arrays()
    counts = replace(world.counts(), empty_cell_steps=rec.events.count_of("empty_cell"))
    results = tally.results(dt=spec.dt, step_seconds=arrays["step_seconds"], arrivals=arrays["arrival_steps"], counts=counts,
                            premise=world.cell_model is not None)
    home = world.home()
    results["arrived"] = float(home.mean())  # the goal checker's verdict at the end, not the latched arrivals
    results["success"] = bool(results["success"] and home.all())
    final = world.positions()  # the last state, whatever rows record_every kept
    results["max_true_goal_distance"] = float(np.linalg.norm(final - world.goals[:, : final.shape[1]], axis=1).max())
    metadata = {**world.metadata(), "loop_seconds": loop_seconds}
    return rec.trace("avoidance", scenario=spec.scenario_name, seed=seed, metadata=metadata, results=results, workspace=workspace)
