"""The instance a run executes: the plan (planned by RPP or read from a file) and its
coordination space (the label-flipping deadlock paper (2021), "Problem Statement" and "Summary of baseline approaches").

Instances of ``placement: flows`` are drawn from ``robots.instance_seed``, or from the
run's seed when that is null; a draw the planner cannot solve (no valid infrastructure)
is replaced by the next draw of the same seed, at most :data:`INSTANCE_ATTEMPTS` times.

Planning costs more than executing one variant of a Fig. 6 instance, and the six policy
variants of one seed execute the same instance, so planned instances are cached in each
process (:func:`planned_instance`, least recently used, keyed by the part of the spec the
plan depends on and the instance seed). Cached arrays are read-only.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import time
from dataclasses import dataclass

import numpy as np

from ..core.errors import InfeasibleError
from ..core.rng import keyed_generator
from ..core.workspace import Workspace
from .coordination_space import CoordinationSpace, build_coordination_space
from .maps import sample_flow_instance, sample_station_instance
from .planner import PlannerSettings, plan_prioritized
from .spec import Spec
from .theory import TheoryReport, check_theory
from .trajectories import Trajectories

INSTANCE_ATTEMPTS = 5
PLAN_CACHE_SIZE = 64


@dataclass(frozen=True)
class Instance:
    """A plan ready to execute.

    Attributes
    ----------
    trajectories:
        the plan ``π_i``.
    space:
        its coordination-space obstacles, labels initialised from the plan.
    instance_seed:
        the seed the starts and goals were drawn from (``None`` when explicit).
    attempt:
        which draw of that seed the planner solved (0 = the first).
    seconds:
        wall time to plan (or read) it and build its coordination space.
    digest:
        a hash of the plan's arrays: runs with equal digests executed the same plan.
    """

    trajectories: Trajectories
    space: CoordinationSpace
    instance_seed: int | None
    attempt: int
    seconds: float
    digest: str

    @functools.cached_property
    def theory(self) -> TheoryReport:
        """Definition 4 and Theorem 4's precondition for the plan (computed once per instance)."""
        return check_theory(self.trajectories, self.space)


@dataclass(frozen=True, eq=False)
class PlanRequest:
    """What a planned instance depends on; equal (and hashed) by ``key`` for the cache."""

    spec: Spec
    instance_seed: int | None
    key: str

    def __hash__(self) -> int:
        return hash(self.key)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PlanRequest) and other.key == self.key


def instance_seed_of(spec: Spec, seed: int) -> int | None:
    """The seed of the random instance: ``robots.instance_seed``, else the run's ``seed``
    (``None`` for explicit starts and goals, which need no draw)."""
    if spec.robots.placement == "explicit":
        return None
    return spec.robots.instance_seed if spec.robots.instance_seed is not None else int(seed)


def plan_request(spec: Spec, seed: int) -> PlanRequest:
    """The cache key of a planned instance: workspace, robots, Δ, planner settings, instance seed."""
    instance_seed = instance_seed_of(spec, seed)
    relevant = {
        "workspace": spec.workspace.model_dump(mode="json"),
        "robots": spec.robots.model_dump(mode="json", exclude={"instance_seed"}),
        "dt": spec.simulation.dt,
        "planner": spec.planner.model_dump(mode="json"),
        "instance_seed": instance_seed,
    }
    return PlanRequest(spec, instance_seed, json.dumps(relevant, sort_keys=True))


def prepare_instance(spec: Spec, seed: int, workspace: Workspace | None = None) -> Instance:
    """The instance run ``seed`` of ``spec`` executes: the plan file's, or a planned one (cached)."""
    if spec.trajectories is None:
        return planned_instance(plan_request(spec, seed))
    t0 = time.perf_counter()
    traj = spec.load_plan(workspace=workspace)
    try:
        return instance_from(traj, None, 0, t0)
    except InfeasibleError as exc:  # name the plan file the instance came from
        raise InfeasibleError(f"{spec.plan_file()}: {exc}") from None


@functools.lru_cache(maxsize=PLAN_CACHE_SIZE)
def planned_instance(request: PlanRequest) -> Instance:
    """Plan the request's instance with RPP, drawing again when a draw is unplannable.

    Raises
    ------
    InfeasibleError
        When no draw of the instance seed (or the explicit endpoints) can be planned.
    """
    spec, t0 = request.spec, time.perf_counter()
    workspace = spec.build_workspace()
    attempts = 1 if request.instance_seed is None else INSTANCE_ATTEMPTS
    failure: InfeasibleError | None = None
    for attempt in range(attempts):
        try:
            starts, goals = robot_endpoints(spec, workspace, request.instance_seed, attempt)
            traj = plan_prioritized(workspace, starts, goals, planner_settings(spec))
        except InfeasibleError as exc:
            failure = exc
            continue
        return instance_from(traj, request.instance_seed, attempt, t0)
    if request.instance_seed is None:
        raise failure
    raise InfeasibleError(f"robots: expected a plannable instance within {attempts} draws of instance seed "
                          f"{request.instance_seed}, received none (last: {failure})")


def robot_endpoints(spec: Spec, workspace: Workspace, instance_seed: int | None, attempt: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals: explicit, or draw ``attempt`` of the flows' boxes (or of the
    warehouse's stations) from ``instance_seed``."""
    r = spec.robots
    if r.placement == "explicit":
        return np.asarray(r.starts, float), np.asarray(r.goals, float)
    keys = ("instance",) if attempt == 0 else ("instance", attempt)
    if r.placement == "stations":
        return sample_station_instance(r.n, keyed_generator(instance_seed, *keys))
    return sample_flow_instance(workspace, r.n, r.radius, keyed_generator(instance_seed, *keys))


def planner_settings(spec: Spec) -> PlannerSettings:
    """The planner's parameters from the scenario (robot radius and speed, Δ, roadmap, search)."""
    p = spec.planner
    return PlannerSettings(radius=spec.robots.radius, speed=spec.robots.speed, dt=spec.simulation.dt,
                           grid_spacing=p.grid_spacing, connection_radius=p.connection_radius,
                           wait_steps=p.wait_steps, max_steps=p.max_steps)


def instance_from(traj: Trajectories, instance_seed: int | None, attempt: int, t0: float) -> Instance:
    """Build the coordination space of ``traj`` and freeze both (the instance may be shared)."""
    space = build_coordination_space(traj)
    read_only(traj)
    read_only(space)
    return Instance(traj, space, instance_seed, attempt, time.perf_counter() - t0, plan_digest(traj))


def read_only(obj: Trajectories | CoordinationSpace) -> None:
    """Mark every array field of the dataclass ``obj`` read-only."""
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray):
            value.flags.writeable = False


def plan_digest(traj: Trajectories) -> str:
    """16 hex digits identifying the plan (positions, lengths, radius, Δ)."""
    h = hashlib.blake2b(digest_size=8)
    for part in (traj.positions, traj.lengths.astype(np.int64), np.array([traj.radius, traj.dt])):
        h.update(np.ascontiguousarray(part).tobytes())
    return h.hexdigest()
