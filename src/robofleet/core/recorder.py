"""The one recorder every family's simulation loop writes through.

The core owns the loop's bookkeeping (as VMAS's environment does for its scenarios): a
family's ``simulate`` declares the arrays it records, then hands one step function to
:meth:`Recorder.run`, which calls it for ``k = 0, 1, …`` until it returns ``True`` (stop
early) or the step budget is spent, moving the progress bar as it goes. What the step
function keeps is only the family's physics and decisions.

Arrays hold, for the whole step budget:

* *state* arrays (``positions``): ``max_steps + 1`` rows, row 0 being the initial state;
* *step* arrays (``controls``, ``step_seconds``): ``max_steps`` rows, row ``k`` being what
  step ``k`` decided.

Their memory is counted against the budget for all those rows when they are declared
(:mod:`~robofleet.core.budget`: refused before anything is allocated), but the rows are
allocated as they are written: storage starts at :data:`FIRST_ROWS` rows and doubles
when a write goes past it (rows not yet written hold the array's fill value), so a run
that stops early never fills the rows of its whole budget.

Decimation: with ``record_every=k`` only the states after steps 0, k, 2k, … and the
step rows of steps 0, k, 2k, … are kept (row ``j`` is step ``j·k``; ``step_seconds`` and
``arrival_steps`` keep every step). Writes go through :meth:`Recorder.put_state` and
:meth:`Recorder.put` for every step as before; the recorder drops the rows it does not
keep. What must see every step (a family's per-run contact counts, say) watches a state
array (``state(..., watch=fn)``): ``fn(row, value)`` is called for every state written,
kept or not, so the per-run results are the same whatever ``record_every``.

:meth:`Recorder.trace` trims them to the steps taken and builds the
:class:`~robofleet.core.trace.Trace`, with the seed, scenario name, robot count, step
count and wall time in its metadata (the core summary keys).

Example
-------
>>> rec = Recorder(max_steps=3, n_robots=2, label="demo")
>>> rec.state("positions", (2, 1), initial=[[0.0], [1.0]])
>>> def step(k):
...     rec.put_state(k + 1, positions=rec["positions"][k] + 1.0)
...     rec.arrive(k + 1, rec["positions"][k + 1, :, 0] >= 2.0)
...     return rec.all_arrived
>>> rec.run(step)
2
>>> rec.arrays()["positions"][:, :, 0].tolist()
[[0.0, 1.0], [1.0, 2.0], [2.0, 3.0]]
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Any, Callable, Iterator

import numpy as np

from .budget import HOW_TO_RAISE, format_bytes, memory_budget, recorded_rows
from .errors import ConfigError, short_repr
from .events import EventLog
from .progress import tracked
from .trace import Trace
from .workspace import Workspace

FIRST_ROWS = 256
"""Rows of storage an array starts with (it doubles as the run goes past them)."""
StepFunction = Callable[[int], "bool | None"]
StateWatcher = Callable[[int, np.ndarray], None]
EVERY_STEP = ("step_seconds",)
"""Per-step arrays kept for every step whatever ``record_every`` (one number a step)."""


def is_integer(value: Any) -> bool:
    """A Python or numpy integer, not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def rows_reached(key: Any, rows: int) -> int:
    """How many leading rows of a ``rows``-row array the index ``key`` reaches (all of
    them for an index counted from the end, a mask, ``...`` and the like)."""
    first = key[0] if isinstance(key, tuple) and key else key
    if isinstance(first, slice):
        reached = range(*first.indices(rows))
        return max(reached[0], reached[-1]) + 1 if reached else 0
    if is_integer(first):
        return int(first) + 1 if first >= 0 else rows
    index = np.asarray(first)
    if index.dtype.kind not in "iu":
        return rows
    if index.size == 0:
        return 0
    return int(index.max()) + 1 if index.min() >= 0 else rows


class RecordedArray:
    """One recorded array of ``rows`` rows, indexed like the numpy array of all its rows,
    whose storage grows (doubling, from :data:`FIRST_ROWS` rows) to the rows an index
    reaches; rows never written hold ``fill``."""

    def __init__(self, rows: int, shape: tuple[int, ...], dtype: Any, fill: Any):
        self.rows, self.fill = rows, fill
        self.data = np.full((min(rows, FIRST_ROWS), *shape), fill, dtype=dtype)

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.rows, *self.data.shape[1:])

    @property
    def dtype(self) -> np.dtype:
        return self.data.dtype

    def __len__(self) -> int:
        return self.rows

    def reserve(self, rows: int) -> None:
        """Storage for at least the first ``rows`` rows: twice the current storage, or
        more when needed, never more than all rows."""
        stored = len(self.data)
        if rows <= stored:
            return
        grown = np.full((min(self.rows, max(rows, 2 * stored)), *self.data.shape[1:]), self.fill, dtype=self.data.dtype)
        grown[:stored] = self.data
        self.data = grown

    def put_row(self, row: int, value: Any) -> None:
        """``self[row] = value`` for a row index ``row ≥ 0`` (the per-step write)."""
        if row >= len(self.data):
            self.reserve(row + 1)
        self.data[row] = value

    def head(self, rows: int) -> np.ndarray:
        """The first ``rows`` rows (a view of the storage)."""
        self.reserve(rows)
        return self.data[:rows]

    def __getitem__(self, key: Any) -> Any:
        self.reserve(rows_reached(key, self.rows))
        return self.data[key]

    def __setitem__(self, key: Any, value: Any) -> None:
        self.reserve(rows_reached(key, self.rows))
        self.data[key] = value

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> np.ndarray:
        return np.array(self.head(self.rows), dtype=dtype, copy=copy)


class Recorder:
    """Per-step arrays, events, arrivals, early stop and the progress bar.

    Parameters
    ----------
    max_steps:
        The step budget (the loop runs at most this many steps).
    n_robots:
        Team size: sizes ``arrival_steps`` and is recorded as ``n_robots``.
    label:
        Progress-bar text (e.g. ``"buavc · 8 robots"``).
    progress:
        Show the progress bar (rich; silent when not on a terminal).
    record_every:
        Keep the rows of every ``record_every``-th step only (see the module docstring).
    """

    def __init__(self, max_steps: int, n_robots: int, *, label: str = "", progress: bool = False, record_every: int = 1):
        if not is_integer(max_steps) or max_steps < 1:
            raise ConfigError(f"max_steps: expected an integer ≥ 1, received {short_repr(max_steps)}")
        if not is_integer(n_robots) or n_robots < 0:
            raise ConfigError(f"n_robots: expected an integer ≥ 0, received {short_repr(n_robots)}")
        if not is_integer(record_every) or record_every < 1:
            raise ConfigError(f"record_every: expected an integer ≥ 1, received {short_repr(record_every)}")
        self.max_steps = int(max_steps)
        self.n_robots = int(n_robots)
        self.record_every = int(record_every)
        self._watchers: dict[str, StateWatcher] = {}
        self._budget = memory_budget()
        self._allocated = 0
        self._reserve("step_seconds", self.max_steps * 8 + self.n_robots * 8)
        if not isinstance(progress, (bool, np.bool_)):
            raise ConfigError(f"progress: expected True or False, received {short_repr(progress)}")
        self.label = label
        self.progress = bool(progress)
        self.events = EventLog()
        self.steps_taken = 0
        self.arrival_steps = np.full(self.n_robots, -1, dtype=np.int64)
        self._state: dict[str, RecordedArray] = {}
        self._step: dict[str, RecordedArray] = {"step_seconds": RecordedArray(self.max_steps, (), float, np.nan)}
        self._started = time.perf_counter()

    # -- declaring arrays -----------------------------------------------------------------
    def state(self, name: str, shape: tuple[int, ...], *, dtype: Any = float, fill: Any = np.nan, initial: Any = None,
              watch: StateWatcher | None = None) -> None:
        """Declare a state array ``(max_steps // record_every + 1, *shape)``; row 0 is
        ``initial`` if given. ``watch(row, value)`` is then called for every state written
        (``initial`` included), whether the row is kept or not."""
        self._state[name] = self._allocate(name, recorded_rows(self.max_steps, self.record_every), shape, dtype, fill)
        if watch is not None:
            self._watchers[name] = watch
        if initial is not None:
            self.put_state(0, **{name: initial})

    def step(self, name: str, shape: tuple[int, ...], *, dtype: Any = float, fill: Any = np.nan) -> None:
        """Declare a per-step array ``(⌈max_steps / record_every⌉, *shape)``."""
        self._step[name] = self._allocate(name, self.step_rows(self.max_steps), shape, dtype, fill)

    def records(self, k: int) -> bool:
        """Whether step ``k``'s rows (and the state after ``k`` steps) are kept."""
        return k % self.record_every == 0

    def step_rows(self, steps: int) -> int:
        """Per-step rows kept of the first ``steps`` steps: those of steps 0, k, 2k, … < ``steps``."""
        return -(-steps // self.record_every)

    def _allocate(self, name: str, rows: int, shape: tuple[int, ...], dtype: Any, fill: Any) -> RecordedArray:
        if name in self._state or name in self._step:
            raise ConfigError(f"recorder: array {name!r}: expected a new name, received one already declared")
        self._reserve(name, rows * int(np.prod(shape, dtype=np.float64)) * np.dtype(dtype).itemsize)
        return RecordedArray(rows, shape, dtype, fill)

    def _reserve(self, name: str, nbytes: float) -> None:
        """Count ``nbytes`` more against the memory budget, refusing before allocating."""
        if self._allocated + nbytes > self._budget:
            raise ConfigError(f"max_steps, n_robots: expected recorded arrays within the memory budget of {format_bytes(self._budget)} "
                              f"(fewer steps or robots, or raise it with {HOW_TO_RAISE}), received {self.n_robots} robots × "
                              f"{self.max_steps} steps needing {format_bytes(self._allocated + nbytes)} at array {name!r}")
        self._allocated += int(nbytes)

    def __getitem__(self, name: str) -> RecordedArray:
        """The array ``name``, indexed like the numpy array of all its rows (row ``j`` is
        step ``j · record_every``; rows past the current step are unset)."""
        return self._state[name] if name in self._state else self._step[name]

    # -- writing --------------------------------------------------------------------------
    def put_state(self, row: int, **values: Any) -> None:
        """Write the state after ``row`` steps (``k + 1`` after step ``k``) of each named
        array: shown to its watcher, kept if ``row`` is a multiple of ``record_every``."""
        for name, value in values.items():
            watcher = self._watchers.get(name)
            if watcher is not None:
                watcher(row, value)
            if self.records(row):
                self._state[name].put_row(row // self.record_every, value)

    def put(self, k: int, **values: Any) -> None:
        """Write step ``k``'s row of each named per-step array (kept if ``k`` is a multiple
        of ``record_every``; the arrays of :data:`EVERY_STEP` keep every step)."""
        for name, value in values.items():
            if name in EVERY_STEP:
                self._step[name].put_row(k, value)
            elif self.records(k):
                self._step[name].put_row(k // self.record_every, value)

    @contextmanager
    def timed(self, k: int) -> Iterator[None]:
        """Time the block as step ``k``'s compute time (``step_seconds[k]``, accumulated)."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            seconds = self._step["step_seconds"]
            so_far = seconds[k]
            seconds.put_row(k, (0.0 if np.isnan(so_far) else so_far) + time.perf_counter() - t0)

    def event(self, step: int, kind: str, **fields: Any) -> None:
        """Record an event ``{"step": step, "kind": kind, **fields}`` (every step's, whatever ``record_every``)."""
        self.events.append({"step": int(step), "kind": kind, **fields})

    def events_for(self, step: int, kind: str, robots: np.ndarray) -> None:
        """One ``kind`` event per robot index flagged in the boolean mask ``robots`` (one
        batch of columns, :meth:`~robofleet.core.events.EventLog.add`)."""
        self.events.add(int(step), kind, robot=np.flatnonzero(robots))

    def arrive(self, step: int, arrived: np.ndarray) -> None:
        """Latch arrivals: robots in the mask ``arrived`` without an arrival step get ``step``
        (and an ``"arrived"`` event); earlier arrivals are kept."""
        newly = np.asarray(arrived, bool) & (self.arrival_steps < 0)
        self.arrival_steps[newly] = step
        self.events_for(step, "arrived", newly)

    @property
    def all_arrived(self) -> bool:
        """Whether every robot has an arrival step."""
        return bool(np.all(self.arrival_steps >= 0))

    # -- the loop -------------------------------------------------------------------------
    def run(self, step: StepFunction) -> int:
        """Call ``step(k)`` for ``k = 0 … max_steps − 1`` until it returns ``True``.

        Returns the number of steps taken. The progress bar shows the steps taken; a run
        that stops early ends with a full bar of its own length.
        """
        with tracked(self.max_steps, self.label, enabled=self.progress) as advance:
            for k in range(self.max_steps):
                stop = step(k)
                self.steps_taken = k + 1
                advance()
                if stop:
                    break
        return self.steps_taken

    # -- results --------------------------------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        """Every array trimmed to the steps taken (the kept rows), plus ``arrival_steps``."""
        t = self.steps_taken
        out = {name: arr.head(recorded_rows(t, self.record_every)) for name, arr in self._state.items()}
        out.update({name: arr.head(t if name in EVERY_STEP else self.step_rows(t)) for name, arr in self._step.items()})
        out["arrival_steps"] = self.arrival_steps.copy()
        return out

    @property
    def wall_seconds(self) -> float:
        """Seconds since the recorder was made."""
        return time.perf_counter() - self._started

    def trace(
        self,
        family: str,
        *,
        scenario: str,
        seed: int,
        metadata: dict[str, Any] | None = None,
        results: dict[str, Any] | None = None,
        workspace: Workspace | None = None,
    ) -> Trace:
        """The run as a :class:`Trace`: arrays, events, and metadata holding the core keys
        (``scenario``, ``seed``, ``n_robots``, ``n_steps``, ``wall_seconds``), the step
        budget and ``record_every``."""
        core = {"scenario": scenario, "seed": int(seed), "n_robots": self.n_robots, "n_steps": self.steps_taken,
                "max_steps": self.max_steps, "record_every": self.record_every, "wall_seconds": self.wall_seconds}
        return Trace(family, self.arrays(), self.events.table(), {**core, **(metadata or {})}, dict(results or {}), workspace)
