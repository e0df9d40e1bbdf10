"""The one recorder every family's simulation loop writes through.

The core owns the loop's bookkeeping (as VMAS's environment does for its scenarios): a
family's ``simulate`` declares the arrays it records, then hands one step function to
:meth:`Recorder.run`, which calls it for ``k = 0, 1, …`` until it returns ``True`` (stop
early) or the step budget is spent, moving the progress bar as it goes. What the step
function keeps is only the family's physics and decisions.

Arrays are preallocated once:

* *state* arrays (``positions``) have ``max_steps + 1`` rows, row 0 being the initial state;
* *step* arrays (``controls``, ``step_seconds``) have ``max_steps`` rows, row ``k`` being
  what step ``k`` decided.

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

from .budget import HOW_TO_RAISE, format_bytes, memory_budget
from .errors import ConfigError, short_repr
from .progress import tracked
from .trace import Trace
from .workspace import Workspace

StepFunction = Callable[[int], "bool | None"]


def is_integer(value: Any) -> bool:
    """A Python or numpy integer, not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


class Recorder:
    """Preallocated per-step arrays, events, arrivals, early stop and the progress bar.

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
    """

    def __init__(self, max_steps: int, n_robots: int, *, label: str = "", progress: bool = False):
        if not is_integer(max_steps) or max_steps < 1:
            raise ConfigError(f"max_steps: expected an integer ≥ 1, received {short_repr(max_steps)}")
        if not is_integer(n_robots) or n_robots < 0:
            raise ConfigError(f"n_robots: expected an integer ≥ 0, received {short_repr(n_robots)}")
        self.max_steps = int(max_steps)
        self.n_robots = int(n_robots)
        self._budget = memory_budget()
        self._allocated = 0
        self._reserve("step_seconds", self.max_steps * 8 + self.n_robots * 8)
        if not isinstance(progress, (bool, np.bool_)):
            raise ConfigError(f"progress: expected True or False, received {short_repr(progress)}")
        self.label = label
        self.progress = bool(progress)
        self.events: list[dict[str, Any]] = []
        self.steps_taken = 0
        self.arrival_steps = np.full(self.n_robots, -1, dtype=np.int64)
        self._state: dict[str, np.ndarray] = {}
        self._step: dict[str, np.ndarray] = {"step_seconds": np.full(self.max_steps, np.nan)}
        self._started = time.perf_counter()

    # -- declaring arrays -----------------------------------------------------------------
    def state(self, name: str, shape: tuple[int, ...], *, dtype: Any = float, fill: Any = np.nan, initial: Any = None) -> None:
        """Declare a state array ``(max_steps + 1, *shape)``; row 0 is ``initial`` if given."""
        self._state[name] = self._allocate(name, self.max_steps + 1, shape, dtype, fill)
        if initial is not None:
            self._state[name][0] = initial

    def step(self, name: str, shape: tuple[int, ...], *, dtype: Any = float, fill: Any = np.nan) -> None:
        """Declare a per-step array ``(max_steps, *shape)``."""
        self._step[name] = self._allocate(name, self.max_steps, shape, dtype, fill)

    def _allocate(self, name: str, rows: int, shape: tuple[int, ...], dtype: Any, fill: Any) -> np.ndarray:
        if name in self._state or name in self._step:
            raise ConfigError(f"recorder: array {name!r}: expected a new name, received one already declared")
        self._reserve(name, rows * int(np.prod(shape, dtype=np.float64)) * np.dtype(dtype).itemsize)
        return np.full((rows, *shape), fill, dtype=dtype)

    def _reserve(self, name: str, nbytes: float) -> None:
        """Count ``nbytes`` more against the memory budget, refusing before allocating."""
        if self._allocated + nbytes > self._budget:
            raise ConfigError(f"max_steps, n_robots: expected recorded arrays within the memory budget of {format_bytes(self._budget)} "
                              f"(fewer steps or robots, or raise it with {HOW_TO_RAISE}), received {self.n_robots} robots × "
                              f"{self.max_steps} steps needing {format_bytes(self._allocated + nbytes)} at array {name!r}")
        self._allocated += int(nbytes)

    def __getitem__(self, name: str) -> np.ndarray:
        """The full preallocated array ``name`` (rows past the current step are unset)."""
        return self._state[name] if name in self._state else self._step[name]

    # -- writing --------------------------------------------------------------------------
    def put_state(self, row: int, **values: Any) -> None:
        """Write state row ``row`` (``k + 1`` after step ``k``) of each named array."""
        for name, value in values.items():
            self._state[name][row] = value

    def put(self, k: int, **values: Any) -> None:
        """Write row ``k`` of each named per-step array."""
        for name, value in values.items():
            self._step[name][k] = value

    @contextmanager
    def timed(self, k: int) -> Iterator[None]:
        """Time the block as step ``k``'s compute time (``step_seconds[k]``, accumulated)."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            seconds = self._step["step_seconds"]
            seconds[k] = (0.0 if np.isnan(seconds[k]) else seconds[k]) + time.perf_counter() - t0

    def event(self, step: int, kind: str, **fields: Any) -> None:
        """Record an event ``{"step": step, "kind": kind, **fields}``."""
        self.events.append({"step": int(step), "kind": kind, **fields})

    def events_for(self, step: int, kind: str, robots: np.ndarray) -> None:
        """One ``kind`` event per robot index flagged in the boolean mask ``robots``."""
        for r in np.flatnonzero(robots):
            self.event(step, kind, robot=int(r))

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
        """Every array trimmed to the steps taken, plus ``arrival_steps``."""
        t = self.steps_taken
        out = {name: arr[: t + 1] for name, arr in self._state.items()}
        out.update({name: arr[:t] for name, arr in self._step.items()})
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
        (``scenario``, ``seed``, ``n_robots``, ``n_steps``, ``wall_seconds``)."""
        core = {"scenario": scenario, "seed": int(seed), "n_robots": self.n_robots, "n_steps": self.steps_taken,
                "max_steps": self.max_steps, "wall_seconds": self.wall_seconds}
        return Trace(family, self.arrays(), list(self.events), {**core, **(metadata or {})}, dict(results or {}), workspace)
