"""Discrete trajectories π_i : {0, …, K_i} → W (the label-flipping deadlock paper (2021), "Problem Statement").

A plan is stored as one padded float64 array ``positions`` of shape ``(n, K_max + 1, 2)``
(rows after ``K_i`` repeat the goal: a finished robot stays parked) and the int array
``lengths`` of the ``K_i``. Plans come from :mod:`.planner` or from a user's file
(:func:`load_trajectories`, CSV or NPZ).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core import arguments
from ..core.config import MAX_MAGNITUDE
from ..core.errors import ScenarioError
from ..core.files import replacing


@dataclass(frozen=True)
class Trajectories:
    """A multi-robot plan sampled at the simulation step.

    Attributes
    ----------
    positions:
        ``(n, K_max + 1, 2)`` float64; ``positions[i, k] = π_i(k)``, padded with the goal.
    lengths:
        ``(n,)`` int; ``K_i``, the first step from which robot ``i`` stays at its goal.
    radius:
        robot radius ``r`` (robots ``i``, ``j`` collide when ``‖π_i − π_j‖ < 2r``).
    dt:
        seconds per step (Δ).
    """

    positions: np.ndarray
    lengths: np.ndarray
    radius: float
    dt: float

    @property
    def n_robots(self) -> int:
        return int(self.positions.shape[0])

    @property
    def starts(self) -> np.ndarray:
        return self.positions[:, 0]

    @property
    def goals(self) -> np.ndarray:
        return self.positions[np.arange(self.n_robots), self.lengths]

    def at(self, progress: np.ndarray) -> np.ndarray:
        """Positions ``(n, 2)`` of the robots at progress ``x`` (``π_i(x_i)``)."""
        return self.positions[np.arange(self.n_robots), np.minimum(progress, self.lengths)]

    def in_plan_time(self, steps: int) -> np.ndarray:
        """Planned positions ``(steps, n, 2)``: every robot executes its plan undisturbed."""
        t = np.minimum(np.arange(steps)[:, None], self.lengths[None, :])
        return self.positions[np.arange(self.n_robots)[None, :], t]


def make_trajectories(paths: list[np.ndarray], radius: float, dt: float, source: str | None = None) -> Trajectories:
    """Validate per-robot paths ``(K_i + 1, 2)`` and pad them into :class:`Trajectories`.

    Trailing repeats of the goal are trimmed so that ``K_i`` is the first step at the goal.

    Raises
    ------
    ScenarioError
        Wrong shape, non-finite values, ``radius <= 0`` or ``dt <= 0``.
    """
    if not is_positive_number(radius):
        raise ScenarioError("robots.radius", "a number > 0", radius, source=source)
    if not is_positive_number(dt):
        raise ScenarioError("simulation.dt", "a number > 0", dt, source=source)
    paths = arguments.sequence(paths, "paths", "(K + 1, 2) arrays, one per robot")
    if len(paths) == 0:
        raise ScenarioError("trajectories", "at least one trajectory", "none", source=source)
    clean = []
    for i, path in enumerate(paths):
        try:
            arr = np.asarray(path, dtype=float)
        except (TypeError, ValueError):
            raise ScenarioError(f"trajectories[{i}]", "an array shaped (K+1, 2) of numbers", path, source=source) from None
        if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 1:
            raise ScenarioError(f"trajectories[{i}]", "an array shaped (K+1, 2)", f"shape {arr.shape}", source=source)
        if not np.all(np.isfinite(arr)):
            raise ScenarioError(f"trajectories[{i}]", "finite coordinates", "NaN or inf", source=source)
        if np.abs(arr).max(initial=0.0) > MAX_MAGNITUDE:  # input validation: as every number of a scenario
            raise ScenarioError(f"trajectories[{i}]", f"coordinates of magnitude at most {MAX_MAGNITUDE:g}", float(np.abs(arr).max()), source=source)
        clean.append(_trim_parking(arr))
    lengths = np.array([len(p) - 1 for p in clean], dtype=np.intp)
    padded = np.empty((len(clean), int(lengths.max()) + 1, 2))
    for i, p in enumerate(clean):
        padded[i, : len(p)] = p
        padded[i, len(p):] = p[-1]
    return Trajectories(padded, lengths, float(radius), float(dt))


def first_plan_collision(traj: Trajectories, chunk_cells: int = 2_000_000) -> tuple[int, int, int, float] | None:
    """The first plan step at which two robots executing the plan undisturbed are closer
    than ``2r`` (``(i, j, step, distance)``), or ``None`` for a collision-free plan.

    The same test the coordination space makes on the plan's own path (a parked robot
    stays at its goal); ``O(K n²)`` in chunks of at most ``chunk_cells`` distances.
    """
    n, steps = traj.n_robots, int(traj.lengths.max(initial=0)) + 1
    per_chunk = max(1, chunk_cells // max(n * n, 1))
    upper = np.triu(np.ones((n, n), dtype=bool), k=1)
    for t0 in range(0, steps, per_chunk):
        t = np.minimum(np.arange(t0, min(steps, t0 + per_chunk))[:, None], traj.lengths[None, :])
        pos = traj.positions[np.arange(n)[None, :], t]
        d2 = ((pos[:, :, None] - pos[:, None, :]) ** 2).sum(-1)
        hit = (d2 < (2 * traj.radius) ** 2) & upper
        if hit.any():
            k, i, j = (int(v) for v in np.argwhere(hit)[0])
            return i, j, t0 + k, float(np.sqrt(d2[k, i, j]))
    return None


def is_positive_number(value: object) -> bool:
    """A finite real number > 0 (not a bool), for the input checks of :func:`make_trajectories`."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)) \
        and bool(np.isfinite(value)) and value > 0


def _trim_parking(path: np.ndarray) -> np.ndarray:
    """Drop trailing copies of the last point (the robot already parked)."""
    moved = np.any(path != path[-1], axis=1)
    last_move = int(np.flatnonzero(moved)[-1]) if moved.any() else -1
    return path[: last_move + 2]


def load_trajectories(path: str | Path, radius: float, dt: float) -> Trajectories:
    """Read a plan from a user's file.

    Formats
    -------
    ``.npz``: either one array ``positions`` ``(n, K + 1, 2)`` (optionally with ``lengths``
    ``(n,)``), or arrays ``robot_0``, ``robot_1``, … each ``(K_i + 1, 2)``.
    ``.csv``: header ``robot,step,x,y``; one row per robot and step, steps ``0..K_i``
    consecutive for each robot.

    Raises
    ------
    ScenarioError
        Unreadable file, unknown extension, wrong shape, non-finite values.
    """
    p = arguments.path(path, "path")
    source = str(p)
    if p.suffix.lower() == ".npz":
        paths = _read_npz(p, source)
    elif p.suffix.lower() == ".csv":
        paths = _read_csv(p, source)
    else:
        raise ScenarioError("trajectories", "a .csv or .npz file", p.name, source=source)
    return make_trajectories(paths, radius, dt, source=source)


def _read_npz(p: Path, source: str) -> list[np.ndarray]:
    try:
        with np.load(p) as npz:
            data = {k: npz[k] for k in npz.files}
    except (OSError, ValueError, EOFError) as exc:
        raise ScenarioError("", "a readable .npz file", str(exc), source=source) from None
    if "positions" in data:
        pos = np.asarray(data["positions"], dtype=float)
        if pos.ndim != 3 or pos.shape[2] != 2:
            raise ScenarioError("positions", "an array shaped (n, K+1, 2)", f"shape {pos.shape}", source=source)
        if "lengths" in data:
            lengths = np.asarray(data["lengths"]).astype(int)
            if lengths.shape != (pos.shape[0],) or np.any(lengths < 0) or np.any(lengths >= pos.shape[1]):
                raise ScenarioError("lengths", f"{pos.shape[0]} integers in [0, {pos.shape[1] - 1}]", data["lengths"], source=source)
            return [pos[i, : lengths[i] + 1] for i in range(pos.shape[0])]
        return list(pos)
    keys = sorted((k for k in data if k.startswith("robot_")), key=lambda k: int(k.split("_")[1]) if k.split("_")[1].isdigit() else -1)
    if not keys:
        raise ScenarioError("", "an array 'positions' or arrays 'robot_0', 'robot_1', ...", sorted(data), source=source)
    return [data[k] for k in keys]


CSV_COLUMNS = ("robot", "step", "x", "y")


def _read_csv(p: Path, source: str) -> list[np.ndarray]:
    """Per-robot paths of a ``robot,step,x,y`` CSV file.

    Errors name the file, the row (spreadsheet numbering: the header is row 1) and the
    column: an empty file, a file with a header only, a row with the wrong number of
    cells, a robot or step that is not a non-negative integer, a coordinate that is not
    a finite number, robot ids that are not ``0..n-1``, steps of a robot that are not
    ``0..K`` consecutive.
    """
    try:
        with p.open(newline="") as handle:
            rows = [row for row in csv.reader(handle) if any(cell.strip() for cell in row)]
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError("", "a readable CSV file with header robot,step,x,y", str(exc), source=source) from None
    if not rows:
        raise ScenarioError("", "a CSV file with header robot,step,x,y and one row per robot and step", "an empty file", source=source)
    header = [cell.strip() for cell in rows[0]]
    if sorted(header) != sorted(CSV_COLUMNS):
        raise ScenarioError("header", "columns robot,step,x,y", header, source=source)
    if len(rows) == 1:
        raise ScenarioError("", "at least one row robot,step,x,y below the header", "a header only", source=source)
    table = _csv_table(rows[1:], [header.index(c) for c in CSV_COLUMNS], source)
    return _csv_paths(table, source)


def _csv_table(rows: list[list[str]], columns: list[int], source: str) -> np.ndarray:
    """The data rows as a float array ``(m, 4)`` in the order robot, step, x, y."""
    table = np.empty((len(rows), 4))
    for r, row in enumerate(rows):
        if len(row) != len(CSV_COLUMNS):
            raise ScenarioError(f"row {r + 2}", "4 cells robot,step,x,y", ",".join(row), source=source)
        for c, (name, index) in enumerate(zip(CSV_COLUMNS, columns)):
            table[r, c] = _csv_cell(row[index], r + 2, name, source)
    return table


def _csv_cell(text: str, row: int, column: str, source: str) -> float:
    """One cell: a non-negative integer for ``robot`` and ``step``, a finite number for ``x``, ``y``."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    integer = column in ("robot", "step")
    if np.isfinite(value) and abs(value) > MAX_MAGNITUDE:  # input validation: as every number of a scenario
        raise ScenarioError(f"row {row}, column {column}", f"a number of magnitude at most {MAX_MAGNITUDE:g}", text.strip(), source=source)
    if not np.isfinite(value) or (integer and (value < 0 or value != int(value))):
        expected = "a non-negative integer" if integer else "a finite number"
        raise ScenarioError(f"row {row}, column {column}", expected, text.strip(), source=source)
    return value


def _csv_paths(table: np.ndarray, source: str) -> list[np.ndarray]:
    """Split a ``(m, 4)`` robot, step, x, y table into per-robot paths (ids ``0..n-1``, steps ``0..K``)."""
    robot, step = table[:, 0].astype(int), table[:, 1].astype(int)
    ids = np.unique(robot)
    if not np.array_equal(ids, np.arange(len(ids))):
        raise ScenarioError("robot", f"ids 0..{len(ids) - 1}", ids.tolist(), source=source)
    paths = []
    for r in ids.tolist():
        mine = np.flatnonzero(robot == r)
        mine = mine[np.argsort(step[mine], kind="stable")]
        if not np.array_equal(step[mine], np.arange(len(mine))):
            raise ScenarioError(f"robot {r}.step", "consecutive steps 0..K", step[mine][:10].tolist(), source=source)
        paths.append(table[mine, 2:4].copy())
    return paths


def save_trajectories(traj: Trajectories, path: str | Path) -> Path:
    """Write a plan as ``.npz`` (``positions`` + ``lengths``) or ``.csv`` (``robot,step,x,y``)."""
    p = Path(path)
    with replacing(p) as temp:
        if p.suffix.lower() == ".npz":
            np.savez(temp, positions=traj.positions, lengths=traj.lengths)
        else:
            rows = [(i, k, *traj.positions[i, k]) for i in range(traj.n_robots) for k in range(int(traj.lengths[i]) + 1)]
            np.savetxt(temp, np.array(rows), delimiter=",", header="robot,step,x,y", comments="", fmt=["%d", "%d", "%.9g", "%.9g"])
    return p
