"""The memory budget: a run whose arrays would not fit is refused before anything is allocated.

Every family's scenario model says what a run of it records (:meth:`SpecModel.run_size`
returns a :class:`RunSize`: steps × robots × bytes, plus whatever else the run holds for
its whole length). :func:`check_run_size` compares that estimate with the budget when a
scenario is loaded (so ``robofleet validate`` refuses what ``robofleet run`` would) and
the :class:`~robofleet.core.recorder.Recorder` checks its actual allocations against the
same budget, as a safety net for specs built in code.

The budget is :data:`DEFAULT_MEMORY_BUDGET` (4 GiB) unless the environment variable
:data:`MEMORY_BUDGET_VARIABLE` (``ROBOFLEET_MEMORY_BUDGET``) says otherwise, e.g.
``ROBOFLEET_MEMORY_BUDGET=512MiB``; the CLI's ``--memory-budget`` sets that variable for
the command (and so for the worker processes of a sweep).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from .errors import ConfigError, Described, ScenarioError, short_repr

DEFAULT_MEMORY_BUDGET = 4 * 2**30
MEMORY_BUDGET_VARIABLE = "ROBOFLEET_MEMORY_BUDGET"
HOW_TO_RAISE = f"{MEMORY_BUDGET_VARIABLE} or --memory-budget"
UNITS = {"": 1, "b": 1, "byte": 1, "bytes": 1,
         **{prefix: 10 ** (3 * power) for power, prefix in enumerate("kmgtp", 1)},
         **{f"{prefix}b": 10 ** (3 * power) for power, prefix in enumerate("kmgtp", 1)},
         **{f"{prefix}ib": 2 ** (10 * power) for power, prefix in enumerate("kmgtp", 1)}}
"""Units of a size, in any letter case: bytes (none, ``B``, ``bytes``), decimal (``k``,
``kB`` … ``P``, ``PB``) and binary (``KiB`` … ``PiB``) multiples, up to the largest budget."""
SIZE_PATTERN = re.compile(r"\s*((?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:e[+-]?[0-9]+)?)\s*([a-z]*)\s*", re.IGNORECASE)
MIN_BUDGET = 2**20
MAX_BUDGET = 2**50
FLOAT_BYTES = 8


def parse_size(text: str | int, where: str = MEMORY_BUDGET_VARIABLE) -> int:
    """Bytes of a size such as ``4GiB``, ``512 MB``, ``2e9`` or an integer (units: :data:`UNITS`).

    Raises
    ------
    ConfigError
        Naming ``where``, for anything else or a size outside 1 MiB … 1 PiB.
    """
    expected = "a size such as 4GiB, 512MiB or 2000000000 (bytes) between 1MiB and 1PiB"
    if isinstance(text, bool) or not isinstance(text, (str, int)):
        raise ConfigError(f"{where}: expected {expected}, received {short_repr(text)}")
    match = SIZE_PATTERN.fullmatch(str(text))
    unit = match.group(2).lower() if match else None
    if match is None or unit not in UNITS:
        raise ConfigError(f"{where}: expected {expected}, received {short_repr(text)}")
    size = float(match.group(1)) * UNITS[unit]
    if not MIN_BUDGET <= size <= MAX_BUDGET:
        raise ConfigError(f"{where}: expected {expected}, received {short_repr(text)}")
    return int(size)


def memory_budget() -> int:
    """The budget in bytes: ``ROBOFLEET_MEMORY_BUDGET`` if set, else 4 GiB."""
    text = os.environ.get(MEMORY_BUDGET_VARIABLE, "").strip()
    return parse_size(text) if text else DEFAULT_MEMORY_BUDGET


@contextmanager
def memory_budget_set(size: str | int | None, where: str = "--memory-budget") -> Iterator[None]:
    """Run the block with the budget ``size`` (``None``: unchanged); the environment
    variable carries it to worker processes started inside the block."""
    if size is None:
        yield
        return
    nbytes = parse_size(size, where)
    previous = os.environ.get(MEMORY_BUDGET_VARIABLE)
    os.environ[MEMORY_BUDGET_VARIABLE] = str(nbytes)
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(MEMORY_BUDGET_VARIABLE, None)
        else:
            os.environ[MEMORY_BUDGET_VARIABLE] = previous


def format_bytes(nbytes: float) -> str:
    """``7.5 GiB``, ``12 MiB``, ``900 B``."""
    for unit, size in (("PiB", 2**50), ("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if nbytes >= size:
            value = nbytes / size
            return f"{value:.3g} {unit}" if value < 1000 else f"{value:.3e} {unit}"
    return f"{int(nbytes)} B"


def recorded_rows(steps: int, record_every: int = 1) -> int:
    """State rows a run of ``steps`` steps keeps when it records every ``record_every``-th
    step: the states after steps 0, k, 2k, … ≤ ``steps`` (the initial state included)."""
    return steps // record_every + 1


@dataclass(frozen=True)
class RunSize:
    """What a run of a scenario holds for its whole length, as the scenario decides it.

    Each ``*_field`` may name several fields, separated by commas; :attr:`fields` names
    them all, and a refusal names every one (:func:`check_run_size`).

    Attributes
    ----------
    steps: the step budget (recorded state arrays have ``steps + 1`` rows).
    robots: the number of robots.
    bytes_per_robot_step: bytes recorded per robot and step (all arrays together).
    steps_field, robots_field: the scenario fields that set them.
    extra_bytes: other memory the run holds throughout (a plan, a grid, logs), if known.
    extra_what: what ``extra_bytes`` is, for the message.
    extra_field: the scenario fields that set ``extra_bytes``, the robots' and steps' too
        if they scale it.
    record_every: only the states and per-step rows of every ``record_every``-th step are
        kept (:func:`recorded_rows`); the per-step compute times are kept for every step.
    row_fields: the scenario fields that set ``bytes_per_robot_step`` or ``record_every``.
    """

    steps: int
    robots: int
    bytes_per_robot_step: int
    steps_field: str = "max_steps"
    robots_field: str = "robots"
    extra_bytes: int = 0
    extra_what: str = ""
    extra_field: str = ""
    record_every: int = 1
    row_fields: str = ""

    @property
    def recorded_bytes(self) -> int:
        """The recorded arrays (recorded steps only) and the per-step compute times (every step)."""
        return recorded_rows(self.steps, self.record_every) * self.robots * self.bytes_per_robot_step + (self.steps + 1) * FLOAT_BYTES

    @property
    def nbytes(self) -> int:
        """The estimate: the recorded arrays plus the extra."""
        return self.recorded_bytes + self.extra_bytes

    @property
    def fields(self) -> tuple[str, ...]:
        """Every scenario field that drives the estimate, each once: those of the larger
        part (recorded arrays, or the extra) first, the extra's only if there is one."""
        recorded = split_fields(self.robots_field, self.steps_field, self.row_fields)
        extra = split_fields(self.extra_field) if self.extra_bytes else ()
        ordered = extra + recorded if self.extra_bytes > self.recorded_bytes else recorded + extra
        return tuple(dict.fromkeys(ordered))

    @property
    def field(self) -> str:
        """:attr:`fields` as one comma-separated string (the field an error names)."""
        return ", ".join(self.fields)

    def describe(self) -> Described:
        """``8 robots × 500 steps ≈ 2.3 MiB, roadmap and plan ≈ 17 MiB``."""
        every = f" (1 in {self.record_every} recorded)" if self.record_every > 1 else ""
        text = f"{self.robots} robots × {self.steps} steps{every} ≈ {format_bytes(self.recorded_bytes)}"
        if self.extra_bytes and self.extra_what:
            text += f", {self.extra_what} ≈ {format_bytes(self.extra_bytes)}"
        return Described(text)


def split_fields(*texts: str) -> tuple[str, ...]:
    """The field names in comma-separated ``texts``, in order."""
    return tuple(name.strip() for text in texts for name in text.split(",") if name.strip())


def check_run_size(size: RunSize | None, source: str | None = None) -> None:
    """Refuse a run whose estimate exceeds the budget: one line naming every field that
    drives the estimate (:attr:`RunSize.fields`), the robot count, the step budget, the
    estimate and how to raise the budget."""
    if size is None:
        return
    budget = memory_budget()
    if size.nbytes > budget:
        which = "this field" if len(size.fields) == 1 else "these fields"
        raise ScenarioError(size.field, f"a run that fits the memory budget of {format_bytes(budget)} "
                            f"(change {which}, or raise it with {HOW_TO_RAISE})", size.describe(), source=source)


def check_allocation(nbytes: int, what: str, field: str, source: str | None = None) -> None:
    """Refuse one structure of ``nbytes`` (a grid, a roadmap...) beyond the budget."""
    budget = memory_budget()
    if nbytes > budget:
        raise ScenarioError(field, f"a {what} that fits the memory budget of {format_bytes(budget)} (raise it with {HOW_TO_RAISE})",
                            Described(f"≈ {format_bytes(nbytes)}"), source=source)
