"""Sweeps: one scenario × a parameter grid × seeds, run through :func:`run_tasks`.

A sweep file (YAML) or mapping has the keys

``scenario``
    A scenario file path (relative to the sweep file), a shipped scenario name
    (``avoidance/three_boxes``) or an inline scenario mapping.
``overrides``
    Optional ``{dotted.path: value}`` applied to the scenario in every run.
``grid``
    ``{dotted.path: [values]}``; the sweep runs the cartesian product, each combination
    applied to the scenario with ``load_scenario(..., overrides=...)``. May be empty. A
    key naming several paths joined by ``+`` (``robots.sigma+workspace.obstacle_sigma``)
    sets all of them to the same value (parameters that move together).
``seeds``
    A count ``n`` (seeds ``spawn_seeds(root_seed, n)``) or an explicit list of seeds.
``root_seed``
    Default 0.
``out``
    Result store directory, relative to the working directory; default
    ``results/<sweep file stem>``.
``metrics``
    Optional list of ``trace.summary()`` keys to keep (default: all): the core keys and
    the scenario family's documented results (``FAMILY.results``); any other key is refused
    before anything runs. A key the family documents for some runs only (flocking's
    mirror-image keys) is empty in the rows of runs whose summary lacks it.

Every combination's scenario is validated before anything runs, so a grid value that
makes the scenario invalid is reported at once. The scenario file is read once, in the
driving process, and travels with the task function; each worker validates each grid
point once (:func:`sweep_spec`, kept for the worker's later runs of that point) and then
only simulates. Each row of the result is the run's
``trace.summary()`` plus ``run_id``, ``seed`` and one column per grid path (named by the
dotted path). ``run_id`` is a stable hash of (scenario, parameters, seed): editing the
scenario or the grid gives new ids, while re-running the same sweep skips what finished.
"""

from __future__ import annotations

import concurrent.futures
import functools
import hashlib
import itertools
import json
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd
from pydantic import field_validator, model_validator

from ..core import arguments
from ..core.errors import ConfigError, Described, ScenarioError, short_repr
from ..core.rng import MAX_SEED, spawn_seeds
from ..core.trace import CORE_SUMMARY_KEYS, to_plain
from ..core.config import DEFAULT_FAMILY, SpecModel, read_mapping, scenario_data, set_path, spec_from_data, validate_model
from ..scenarios import catalogue, family, read_scenario, simulate
from .executors import Executor, as_executor
from .store import ERROR_COLUMN, ResultStore
from .tasks import run_tasks

RESERVED_COLUMNS = ("run_id", "seed", ERROR_COLUMN)
MAX_RUNS = 1_000_000
"""The most runs (grid points × seeds) one sweep may hold: every run is planned, and
every grid point validated, before anything runs."""


class SweepSpec(SpecModel):
    """The validated content of a sweep file (see the module docstring)."""

    scenario: Any
    overrides: Any = {}
    grid: Any = {}
    seeds: Any
    root_seed: Any = 0
    out: str | None = None
    metrics: Any = None

    @field_validator("scenario", mode="before")
    @classmethod
    def _scenario(cls, value):
        if isinstance(value, str) and value.strip():
            return value
        if isinstance(value, Mapping):
            return dict(value)
        raise ScenarioError("", "a scenario file path or an inline scenario mapping", value)

    @field_validator("overrides", mode="before")
    @classmethod
    def _overrides(cls, value):
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise ScenarioError("", "a mapping {dotted.path: value}", value)
        for key in value:
            if not is_field_path(key):
                raise ScenarioError("", "dotted field paths such as robots.radius as keys", key)
        return dict(value)

    @field_validator("grid", mode="before")
    @classmethod
    def _grid(cls, value):
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise ScenarioError("", "a mapping {dotted.path: [values]}", value)
        for key, values in value.items():
            if not isinstance(key, str) or not all(is_field_path(part) for part in key.split("+")):
                raise ScenarioError("", "dotted field paths such as robots.radius (or several joined by +) as keys", key)
            if key in RESERVED_COLUMNS:
                raise ScenarioError(key, f"a scenario field path (not one of the reserved columns {list(RESERVED_COLUMNS)})", key)
            if not isinstance(values, list) or not values:
                raise ScenarioError(key, "a non-empty list of values", values)
            repeated = next((v for i, v in enumerate(values) if v in values[:i]), None) if len(values) > 1 else None
            if repeated is not None:
                raise ScenarioError(key, "distinct values (each grid point once)", repeated)
        return dict(value)

    @field_validator("seeds", mode="before")
    @classmethod
    def _seeds(cls, value):
        if is_int(value):
            if not 0 < value <= MAX_RUNS:
                raise ScenarioError("", f"a number of seeds in [1, {MAX_RUNS:,}] or a non-empty list of seeds", value)
            return int(value)
        if isinstance(value, list) and value:
            if len(value) > MAX_RUNS:
                raise ScenarioError("", f"at most {MAX_RUNS:,} seeds", f"{len(value):,} seeds")
            if not all(is_int(s) and 0 <= s <= MAX_SEED for s in value):
                raise ScenarioError("", "a list of integer seeds in [0, 2**63)", value)
            if len(set(value)) != len(value):
                raise ScenarioError("", "distinct seeds", value)
            return [int(s) for s in value]
        raise ScenarioError("", "a positive number of seeds or a non-empty list of seeds", value)

    @field_validator("root_seed", mode="before")
    @classmethod
    def _root_seed(cls, value):
        if not is_int(value) or not 0 <= value <= MAX_SEED:
            raise ScenarioError("", "an integer in [0, 2**63)", value)
        return int(value)

    @model_validator(mode="after")
    def _size(self):
        points = math.prod(len(values) for values in self.grid.values())
        runs = points * (self.seeds if isinstance(self.seeds, int) else len(self.seeds))
        if runs > MAX_RUNS:
            raise ScenarioError("grid", f"at most {MAX_RUNS:,} runs (grid points × seeds)", Described(f"{points:,} grid points × seeds = {runs:,} runs"))
        return self

    @field_validator("metrics", mode="before")
    @classmethod
    def _metrics(cls, value):
        if value is None:
            return None
        if not isinstance(value, list) or not value or not all(isinstance(m, str) and m for m in value):
            raise ScenarioError("", "a non-empty list of summary keys", value)
        if len(set(value)) != len(value):
            raise ScenarioError("", "distinct summary keys", value)
        return list(value)


def is_field_path(key: Any) -> bool:
    """Whether ``key`` is a dotted field path such as ``robots.radius``."""
    return isinstance(key, str) and bool(key) and all(part for part in key.split("."))


def expand_overrides(combination: Mapping[str, Any]) -> dict[str, Any]:
    """Scenario overrides of a grid combination: a ``a+b`` key sets both ``a`` and ``b``."""
    return {path: value for key, value in combination.items() for path in key.split("+")}


def is_int(value: object) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


@dataclass(frozen=True)
class SweepPlan:
    """A validated sweep, expanded into tasks.

    Attributes
    ----------
    source:
        the sweep file (``None`` for a mapping).
    scenario:
        the scenario mapping every task starts from (shipped to workers).
    grid_keys:
        the grid's dotted paths, in file order (also the parameter column names).
    combinations:
        one ``{path: value}`` dict per grid point, in product order.
    seeds:
        the seeds every combination runs with.
    tasks:
        ``combinations × seeds`` task dicts (``run_id``, ``seed``, parameters).
    fn:
        the picklable task function (simulate one task, return its summary).
    out:
        the result store directory.
    """

    source: str | None
    scenario: dict
    grid_keys: tuple[str, ...]
    combinations: tuple[dict, ...]
    seeds: tuple[int, ...]
    tasks: tuple[dict, ...]
    fn: Callable[[dict], dict]
    out: Path


SPEC_CACHE_SIZE = 1024
"""Validated grid-point scenarios a process keeps (least recently used dropped first)."""
_specs: OrderedDict[tuple[str, str], SpecModel] = OrderedDict()
_specs_lock = threading.Lock()  # runs on a thread pool share the cache


def sweep_spec(base: Mapping[str, Any], source: str | None, digest: str, overrides: Mapping[str, Any]) -> SpecModel:
    """The validated scenario of one grid point: ``base`` (a scenario mapping read from
    ``source``, whose content hashes to ``digest``) with ``overrides`` applied.

    Validated exactly as ``load_scenario(source, overrides=overrides)`` validates (same
    model, same file named in errors and kept as ``spec.source``), once per process and
    grid point: the specs are frozen, so later runs of the point reuse it.
    """
    key = (digest, json.dumps(to_plain(dict(overrides)), sort_keys=True, default=str))
    with _specs_lock:
        spec = _specs.get(key)
        if spec is not None:
            _specs.move_to_end(key)
            return spec
    try:
        data, _ = scenario_data(base, overrides)
    except ScenarioError as exc:
        raise (exc.with_source(source) if source else exc) from None
    spec = spec_from_data(family(data.setdefault("family", DEFAULT_FAMILY), source).spec, data, source)
    with _specs_lock:
        _specs[key] = spec
        if len(_specs) > SPEC_CACHE_SIZE:
            _specs.popitem(last=False)
    return spec


def simulate_task(task: dict, *, scenario: dict, source: str | None, digest: str, fixed: Mapping[str, Any],
                  grid_keys: tuple[str, ...], metrics: tuple[str, ...] | None) -> dict:
    """Run one sweep task: the scenario with the sweep's overrides and the task's grid
    values (:func:`sweep_spec`), at the task's seed."""
    spec = sweep_spec(scenario, source, digest, {**fixed, **expand_overrides({key: task[key] for key in grid_keys})})
    summary = simulate(spec, seed=task["seed"], progress=False).summary()
    if metrics is None:
        return summary
    return {m: summary.get(m) for m in metrics}


def stable_run_id(scenario: Mapping, parameters: Mapping, seed: int) -> str:
    """A hash of (scenario, parameters, seed), the same in every process and session."""
    text = json.dumps({"scenario": to_plain(scenario), "parameters": to_plain(parameters), "seed": int(seed)}, sort_keys=True, default=str)
    return hashlib.blake2b(text.encode(), digest_size=10).hexdigest()


def run_ids(scenario: Mapping, parameters: Mapping, seeds: tuple[int, ...]) -> list[str]:
    """``[stable_run_id(scenario, parameters, seed) for seed in seeds]``, hashing the
    scenario and parameters once: the JSON text :func:`stable_run_id` hashes is
    ``{"parameters": P, "scenario": S, "seed": N}`` (keys sorted), so the hash state after
    its part before ``N`` is copied for each seed."""
    def text(value: Any) -> str:
        return json.dumps(to_plain(value), sort_keys=True, default=str)

    head = hashlib.blake2b(f'{{"parameters": {text(parameters)}, "scenario": {text(scenario)}, "seed": '.encode(), digest_size=10)
    out = []
    for seed in seeds:
        hasher = head.copy()
        hasher.update(f"{int(seed)}}}".encode())
        out.append(hasher.hexdigest())
    return out


def plan_sweep(sweep_file_or_mapping: str | Path | Mapping[str, Any], out: str | Path | None = None) -> SweepPlan:
    """Read and validate a sweep, check every grid combination's scenario, build the tasks.

    Raises
    ------
    ScenarioError
        One line naming the sweep file and field: unknown keys, wrong types, an empty
        value list, a non-positive seed count, or a grid combination whose scenario is
        invalid (with the scenario's own field, expectation and value).
    """
    if not isinstance(sweep_file_or_mapping, (str, Path, Mapping)) or (isinstance(sweep_file_or_mapping, str) and not sweep_file_or_mapping.strip()):
        raise ConfigError(f"sweep: expected a sweep file path, a shipped sweep name or a mapping, received {short_repr(sweep_file_or_mapping)}")
    arguments.path(out, "out", optional=True)
    ref = catalogue.resolve(sweep_file_or_mapping, "sweeps") if isinstance(sweep_file_or_mapping, (str, Path)) else sweep_file_or_mapping
    data, source = read_mapping(ref)
    spec: SweepSpec = validate_model(SweepSpec, data, source)
    scenario_ref = sweep_scenario(spec, source)
    try:
        base = SweepScenario.read(scenario_ref)
    except ScenarioError as exc:
        raise named_in_sweep(exc, {}, source) from None
    grid_keys = tuple(spec.grid)
    combinations = tuple(
        check_combination(base, dict(zip(grid_keys, values)), source, spec.overrides)
        for values in itertools.product(*spec.grid.values())
    )
    check_distinct_points(combinations, source)
    scenario = read_mapping(base.mapping)[0]
    for key, value in spec.overrides.items():
        set_path(scenario, key, value)
    if spec.metrics is not None:
        check_metrics(spec.metrics, scenario.get("family", DEFAULT_FAMILY), source)
    seeds = tuple(spawn_seeds(spec.root_seed, spec.seeds) if isinstance(spec.seeds, int) else spec.seeds)
    tasks = tuple(
        {"run_id": run_id, "seed": seed, **combination}
        for combination in combinations
        for run_id, seed in zip(run_ids(scenario, combination, seeds), seeds)
    )
    fn = functools.partial(simulate_task, scenario=base.mapping, source=base.source, digest=base.digest, fixed=dict(spec.overrides),
                           grid_keys=grid_keys, metrics=None if spec.metrics is None else tuple(spec.metrics))
    stem = Path(source).stem if source else "sweep"
    out_dir = Path(out) if out is not None else Path(spec.out) if spec.out else Path("results") / stem
    return SweepPlan(source, scenario, grid_keys, combinations, seeds, tasks, fn, out_dir)


@dataclass(frozen=True)
class SweepScenario:
    """The scenario a sweep's runs start from, read once: its mapping, its file (``None``
    for an inline mapping) and a hash of its content (which keys the workers' caches)."""

    mapping: dict
    source: str | None
    digest: str

    @classmethod
    def read(cls, ref: str | dict) -> SweepScenario:
        mapping, source = read_scenario(ref)
        text = json.dumps({"source": source, "scenario": to_plain(mapping)}, sort_keys=True, default=str)
        return cls(mapping, source, hashlib.blake2b(text.encode(), digest_size=16).hexdigest())

    def spec(self, overrides: Mapping[str, Any]) -> SpecModel:
        return sweep_spec(self.mapping, self.source, self.digest, overrides)


def sweep_scenario(spec: SweepSpec, source: str | None) -> str | dict:
    """What every task of the sweep loads: a scenario file path (a path relative to the
    sweep file, or a shipped scenario name resolved through the catalogue), kept as a path
    so that files the scenario names (a coordination plan) resolve beside it; or the
    inline mapping."""
    if not isinstance(spec.scenario, str):
        return dict(spec.scenario)
    base = Path(source).parent if source else None
    try:
        return str(catalogue.resolve(spec.scenario, "scenarios", base))
    except ScenarioError as exc:
        raise ScenarioError("scenario", exc.expected, exc.received, source=source) from None


def check_combination(scenario: SweepScenario, combination: dict, source: str | None, fixed: Mapping[str, Any] | None = None) -> dict:
    """Validate the scenario with one grid combination; re-raise naming the sweep file.

    Returns the combination with each value as the validated scenario holds it (e.g. the
    YAML string ``"1e-3"`` becomes ``0.001`` for a float field), so parameter columns
    and run ids carry the values that were actually simulated.
    """
    try:
        spec = scenario.spec({**(fixed or {}), **expand_overrides(combination)})
    except ScenarioError as exc:
        raise named_in_sweep(exc, combination, source) from None
    dumped = spec.model_dump(mode="json")
    return {key: get_path(dumped, key.split("+")[0], value) for key, value in combination.items()}


def named_in_sweep(exc: ScenarioError, combination: Mapping[str, Any], source: str | None) -> ScenarioError:
    """A scenario's error (reading it, or with one grid combination) naming the sweep file first."""
    where = "scenario" if not combination else "grid " + ", ".join(f"{k}={v!r}" for k, v in combination.items())
    inner = f"{exc.source or 'inline scenario'}" + (f": {exc.field}" if exc.field else "")
    return ScenarioError(f"{where} → {inner}", exc.expected, exc.received, source=source)


def check_metrics(metrics: list[str], family_name: str, source: str | None) -> None:
    """Refuse a metric that no summary of the family has (one line naming it and the keys there are)."""
    known = [*CORE_SUMMARY_KEYS, *family(family_name, source).results]
    unknown = [m for m in metrics if m not in known]
    if unknown:
        raise ScenarioError("metrics", f"summary keys of {family_name} runs ({', '.join(known)})",
                            unknown[0] if len(unknown) == 1 else unknown, source=source)


def check_distinct_points(combinations: tuple[dict, ...], source: str | None) -> None:
    """Refuse two grid points that are the same once validated (``1e-3`` and ``0.001``):
    they would be one run id."""
    seen: dict[str, dict] = {}
    for combination in combinations:
        key = json.dumps(to_plain(combination), sort_keys=True, default=str)
        if key in seen:
            raise ScenarioError("grid", "distinct grid points once validated", combination, source=source)
        seen[key] = combination


def get_path(mapping: Mapping, dotted: str, default: Any) -> Any:
    """``mapping["a"]["b"]`` for ``dotted == "a.b"`` (numeric parts index lists), or
    ``default`` if absent."""
    node: Any = mapping
    for key in dotted.split("."):
        if isinstance(node, list) and key.isdigit() and int(key) < len(node):
            node = node[int(key)]
        elif isinstance(node, Mapping) and key in node:
            node = node[key]
        else:
            return default
    return node


def run_sweep(
    sweep_file_or_mapping: str | Path | Mapping[str, Any],
    executor: str | Executor | concurrent.futures.Executor = "process",
    scheduler: str | None = None,
    progress: bool = True,
    *,
    workers: int | None = None,
    out: str | Path | None = None,
) -> pd.DataFrame:
    """Run a sweep (scenario × grid × seeds), resuming from its result store.

    Parameters
    ----------
    sweep_file_or_mapping:
        A sweep YAML file or mapping (see the module docstring).
    executor, scheduler, workers, progress:
        As for :func:`run_tasks`.
    out:
        Result store directory, overriding the sweep's ``out``.

    Returns
    -------
    pandas.DataFrame
        The rows of this sweep's tasks (finished now or by an earlier run), in task
        order; the columns ``run_id``, ``seed``, one per grid path, the summary keys (by
        name) and ``error``. ``frame.attrs`` holds ``store`` (the directory), ``grid`` (the grid
        paths) and ``other_rows`` (rows in the store from other sweeps).
    """
    as_executor(executor)
    workers = arguments.count(workers, "workers", minimum=1, optional=True)
    progress = arguments.flag(progress, "progress")
    plan = plan_sweep(sweep_file_or_mapping, out)
    every = run_tasks(plan.fn, plan.tasks, ResultStore(plan.out), executor=executor, scheduler=scheduler, workers=workers, progress=progress)
    order = {task["run_id"]: index for index, task in enumerate(plan.tasks)}
    mine = every[every["run_id"].isin(order)]
    frame = mine.sort_values("run_id", key=lambda ids: ids.map(order), kind="stable").reset_index(drop=True)
    leading = ["run_id", "seed", *plan.grid_keys]
    frame = frame[leading + [c for c in frame.columns if c not in leading]]
    frame.attrs.update(store=str(plan.out), grid=list(plan.grid_keys), other_rows=int(len(every) - len(mine)))
    return frame


def summarize_sweep(frame: pd.DataFrame, grid_keys: list[str] | tuple[str, ...] | None = None) -> pd.DataFrame:
    """Means of the numeric and boolean result columns per grid combination.

    Adds ``runs`` (tasks per combination) and ``failed`` (tasks that raised); means are
    over the rows without error. ``grid_keys`` defaults to ``frame.attrs["grid"]``.
    """
    arguments.instance(frame, pd.DataFrame, "frame", "a pandas DataFrame of sweep rows (run_sweep returns one)")
    keys = list(frame.attrs.get("grid", []) if grid_keys is None else arguments.sequence(grid_keys, "grid_keys", "column names"))
    missing = [key for key in keys if key not in frame.columns]
    if missing:
        raise ConfigError(f"grid_keys: expected columns of the frame, received {missing}")
    ok = frame[frame[ERROR_COLUMN].isna()] if ERROR_COLUMN in frame else frame
    skip = set(keys) | set(RESERVED_COLUMNS)
    values = [c for c in ok.columns if c not in skip and (pd.api.types.is_numeric_dtype(ok[c]) or pd.api.types.is_bool_dtype(ok[c]))]
    numeric = ok[keys + values].copy()
    for column in values:
        numeric[column] = numeric[column].astype(float)
    counts = frame.assign(failed=frame[ERROR_COLUMN].notna() if ERROR_COLUMN in frame else False)
    if keys:
        means = numeric.groupby(keys, dropna=False, sort=False)[values].mean()
        tally = counts.groupby(keys, dropna=False, sort=False).agg(runs=("run_id", "nunique"), failed=("failed", "sum"))
        return tally.join(means).reset_index()
    means = numeric[values].mean().to_frame().T
    return pd.concat([pd.DataFrame({"runs": [frame["run_id"].nunique()], "failed": [int(counts["failed"].sum())]}), means], axis=1)
