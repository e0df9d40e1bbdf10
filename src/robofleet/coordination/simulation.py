"""The coordination family's one loop: spec → world → steps → :class:`~robofleet.core.trace.Trace`.

:func:`simulate` builds the workspace, prepares the instance (the plan and its
coordination space, :mod:`.instance`), wires a :class:`~.plan_execution.PlanExecutor`
with the map's disturbance probabilities (known, or learned online for the flip tests)
and hands one step function to :class:`~robofleet.core.recorder.Recorder`, which
preallocates the arrays and moves the progress bar.

Step ``k`` of the recorder executes the move from ``t = k`` to ``k + 1`` (disturbances,
``x(t + 1) = x(t) + a(t) δ(t)``) and then the decisions of ``t = k + 1`` (flip tests, Eq. 1),
so that the run stops right after the move that finished it, or at the decision that
found a deadlock. Recorded arrays (rows ``0..n_steps``):

``positions`` ``(n, 2)``, ``progress`` ``(n, 1)`` (``x_i``), ``waiting`` ``(n, 1)`` (the first
case of Eq. 1), ``disturbed`` ``(n, 1)`` per step (``δ_i(t) = 0``), ``step_seconds``,
``arrival_steps``, and ``plan`` ``(K_max + 1, n, 2)``, the planned trajectories.

Seeds: ``simulate(spec, seed)`` passes ``seed`` through :func:`~robofleet.core.rng.resolve_seed`;
the disturbances (one stream per robot and block of steps) and, when
``robots.instance_seed`` is null, the instance derive from it.
"""

from __future__ import annotations

import time

import numpy as np

from ..core.family import expect_spec
from ..core.recorder import Recorder
from ..core.rng import resolve_seed
from ..core.trace import Trace
from ..core.workspace import Workspace
from .instance import Instance, prepare_instance
from .label_flipping import KnownProbabilities, LearnedProbabilities
from .maps import probability_map
from .metrics import run_results
from .plain_steps import PlainStepRows
from .plan_execution import DISTURBANCE_BLOCK, Decision, Estimate, ExecutionState, PlanExecutor, Variant
from .spec import Spec

FAMILY_NAME = "coordination"


def simulate(spec: Spec, seed: int | None = None, progress: bool = False) -> Trace:
    """Execute the scenario's plan with its policy under random disturbances.

    Parameters
    ----------
    spec:
        The scenario.
    seed:
        Seed of every random draw (disturbances; the instance when ``robots.instance_seed``
        is null); ``None`` draws one. Recorded as ``trace.seed``.
    progress:
        Show a progress bar over the step budget.

    Returns
    -------
    Trace
        Arrays, events (``flip``, ``flip_refused``, ``arrived``, ``collision``,
        ``deadlock``, ``timeout``), metadata and the results of :mod:`~robofleet.coordination.metrics`.
    """
    expect_spec(spec, Spec, "coordination")  # input validation: a validated coordination scenario
    seed = resolve_seed(seed)
    workspace = spec.build_workspace()
    instance = prepare_instance(spec, seed, workspace)
    variant = Variant(spec.policy.method, spec.policy.deadlock_check)
    executor = make_executor(spec, instance, workspace, variant)
    rec = Recorder(spec.simulation.max_steps, instance.trajectories.n_robots,
                   label=f"{FAMILY_NAME} · {instance.trajectories.n_robots} robots · {variant.name}", progress=progress)
    loop = RecordedExecution(rec, executor, executor.start(seed, events=rec.events))
    rec.run(loop.step)
    executor.conclude(loop.state, rec.steps_taken)
    return execution_trace(spec, rec, loop.state, instance, workspace, variant, seed)


def make_executor(spec: Spec, instance: Instance, workspace: Workspace, variant: Variant) -> PlanExecutor:
    """A :class:`PlanExecutor` wired with the map's probabilities, known or learned online."""
    traj = instance.trajectories
    probability = probability_map(workspace, traj.positions, spec.disturbance.base_probability)
    cells = None
    if spec.policy.estimate is Estimate.LEARNED:
        cells = map_cells(traj.positions, workspace, spec.policy.learned_cell)
        times = LearnedProbabilities(cells, int(cells.max()) + 1, traj.dt, prior=spec.disturbance.base_probability)
    else:
        times = KnownProbabilities(probability, traj.dt)
    return PlanExecutor(traj, instance.space, variant, times, probability, resolution=spec.policy.resolution,
                        observe_cells=cells, optimal=spec.policy.optimal.settings(), btpg_budget=spec.policy.btpg_budget)


def map_cells(points: np.ndarray, workspace: Workspace, cell: float) -> np.ndarray:
    """Index of the square grid cell (side ``cell``) of each point ``(..., 2)``, for the learned estimate."""
    xmin, ymin, xmax, _ = workspace.extent
    nx = int(np.ceil((xmax - xmin) / cell)) + 1
    ix = np.clip(((points[..., 0] - xmin) // cell).astype(int), 0, nx - 1)
    iy = np.clip(((points[..., 1] - ymin) // cell).astype(int), 0, None)
    return iy * nx + ix


class RecordedExecution:
    """The recorder's step function: one move and the next step's decisions per call.

    Runs of plain steps (:mod:`.plain_steps`) are executed by one compiled call, which
    writes their rows into the recorder's arrays at once; the recorder's later calls for
    those steps return at once. Their ``step_seconds`` share the call's wall time equally.

    Parameters
    ----------
    rec:
        the recorder (arrays are declared here).
    executor:
        the policy on the plan.
    state:
        the executor's state at ``t = 0``.
    """

    def __init__(self, rec: Recorder, executor: PlanExecutor, state: ExecutionState):
        self.rec, self.executor, self.state = rec, executor, state
        traj = executor.traj
        n = traj.n_robots
        rec.state("positions", (n, 2), initial=traj.starts)
        rec.state("progress", (n, 1), dtype=np.int64, fill=0, initial=0)
        rec.state("waiting", (n, 1), dtype=bool, fill=False)
        rec.step("disturbed", (n, 1), dtype=bool, fill=False)
        rec.arrive(0, state.x >= traj.lengths)
        self.decision = self.decide(0)
        self.executed = 0
        self.scratch = PlainStepRows.empty(DISTURBANCE_BLOCK, n)

    def decide(self, t: int) -> Decision:
        """Decisions of step ``t`` (flip tests, Eq. 1), recorded in row ``t`` of ``waiting``."""
        decision = self.executor.decide(self.state, t) if t < self.rec.max_steps else self.executor.settle(self.state)
        self.rec.put_state(t, waiting=decision.waiting[:, None])
        return decision

    def step(self, k: int) -> bool:
        """Move from ``t = k`` to ``k + 1``, decide at ``k + 1``; ``True`` when the run ends."""
        rec, state, traj = self.rec, self.state, self.executor.traj
        if k < self.executed:  # done by the compiled block of an earlier call
            return False
        if self.decision.stop:  # finished or deadlocked at t = 0: nothing moves
            rec.put_state(k + 1, positions=traj.at(state.x), progress=state.x[:, None], waiting=self.decision.waiting[:, None])
            return True
        if self.run_plain_steps(k):
            return False
        with rec.timed(k):
            hit = self.executor.move(state, self.decision, k)
            rec.put(k, disturbed=hit[:, None])
            rec.put_state(k + 1, positions=traj.at(state.x), progress=state.x[:, None])
            rec.arrive(k + 1, state.x >= traj.lengths)
            self.decision = self.decide(k + 1)
        return self.decision.stop

    def run_plain_steps(self, k: int) -> bool:
        """Execute the plain steps from ``k`` on in one compiled call and record them;
        ``False`` (nothing done) when step ``k`` is not plain."""
        t0 = time.perf_counter()
        done, decision = self.executor.plain_steps(self.state, self.decision, k, self.rec.max_steps, self.scratch)
        if done == k:
            return False
        rows, traj = done - k, self.executor.traj
        progress, waiting = self.scratch.progress[:rows], self.scratch.waiting[:rows]
        positions = traj.positions[np.arange(traj.n_robots)[None, :], np.minimum(progress, traj.lengths)]
        put_rows(self.rec, k + 1, positions=positions, progress=progress[:, :, None], waiting=waiting[:, :, None])
        put_rows(self.rec, k, disturbed=self.scratch.disturbed[:rows, :, None])
        self.decision, self.executed = decision, done
        self.rec["step_seconds"][k:done] = (time.perf_counter() - t0) / rows
        return True


def put_rows(rec: Recorder, first: int, **values: np.ndarray) -> None:
    """Write one row of each value per step: the states after steps ``first, first + 1, …``
    (or the per-step rows of those steps), kept as :meth:`Recorder.put_state` and
    :meth:`Recorder.put` keep them (every ``record_every``-th)."""
    every = getattr(rec, "record_every", 1)
    for name, value in values.items():
        if every == 1:
            rec[name][first:first + len(value)] = value
            continue
        rows = np.arange(first, first + len(value))
        kept = rows % every == 0
        rec[name][rows[kept] // every] = value[kept]


def execution_trace(spec: Spec, rec: Recorder, state: ExecutionState, instance: Instance, workspace: Workspace,
                    variant: Variant, seed: int) -> Trace:
    """The run as a :class:`Trace`: the recorder's arrays plus the plan, metadata, results."""
    traj = instance.trajectories
    report = instance.theory
    metadata = {
        "method": variant.name, "dt": traj.dt, "radius": traj.radius, "goals": traj.goals.tolist(),
        "goal_tolerance": 0.0, "base_probability": spec.disturbance.base_probability,
        "instance_seed": instance.instance_seed,
    }
    results = run_results(variant, state, rec.arrival_steps, instance, report, probability_map(
        workspace, traj.positions, spec.disturbance.base_probability), rec.steps_taken, spec.simulation.max_steps)
    trace = rec.trace(FAMILY_NAME, scenario=spec.scenario_name, seed=seed, metadata=metadata, results=results,
                      workspace=workspace)
    trace.arrays["plan"] = np.transpose(traj.positions, (1, 0, 2)).copy()
    return trace
