"""A progress bar for long loops (rich), silent when disabled or not on a terminal, and the
notice that numba is compiling kernels.

The compiled kernels are cached on disk (every ``numba.njit`` has ``cache=True``), so only
the first run in a new environment compiles them, for several seconds; meanwhile the
progress line says so (:func:`compile_notice`).
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import Any, Iterator

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TaskID, TextColumn, TimeElapsedColumn, TimeRemainingColumn

COMPILING = "compiling kernels (first run only)…"
"""What the progress line says while numba compiles."""

LIVE_BARS: list[tuple[Progress, TaskID, str]] = []
"""The bars :func:`tracked` shows now (bar, task, description), innermost last."""


def progress_bar(total: int | None, description: str, enabled: bool = True) -> Progress:
    """A rich ``Progress`` with bar, count, elapsed time and ETA (use as a context manager)."""
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        disable=not enabled,
        transient=False,
    )


@contextmanager
def tracked(total: int | None, description: str, enabled: bool = True) -> Iterator["callable"]:
    """Context manager yielding ``advance(n=1)`` that moves a progress bar forward.

    A loop that ends early on its own (a run whose robots all arrived) shows a full bar of
    the steps it took; one left by an exception keeps its partial bar.
    """
    if not enabled:  # no bar to move: a call per loop step costs nothing
        yield lambda n=1: None
        return
    with progress_bar(total, description, enabled) as bar:
        task = bar.add_task(description, total=total)
        LIVE_BARS.append((bar, task, description))
        try:
            yield lambda n=1: bar.advance(task, n)
        finally:
            LIVE_BARS.remove((bar, task, description))
        bar.update(task, total=bar.tasks[0].completed)


@contextmanager
def compile_notice(enabled: bool = True) -> Iterator[None]:
    """While numba compiles inside this block, the live progress bar reads
    ``<description> · compiling kernels (first run only)…``; before a bar shows (a run's
    set-up), a status line of its own says it. Nested blocks announce once."""
    global _announcing
    if not enabled or _announcing:
        yield
        return
    from numba.core import event

    _announcing = True
    try:
        with event.install_listener("numba:compile", _compile_listener(event.Listener)()):
            yield
    finally:
        _announcing = False


_announcing = False


def _compile_listener(base: type) -> type:
    """A numba event listener (subclass of ``base``) showing :data:`COMPILING` from the
    outermost compile's start to its end (numba compiles one function at a time)."""

    class CompileListener(base):  # type: ignore[misc, valid-type]
        def __init__(self) -> None:
            self.depth = 0
            self.restore: Any = None

        def on_start(self, event: Any) -> None:
            self.depth += 1
            if self.depth == 1:
                self.restore = show_compiling()

        def on_end(self, event: Any) -> None:
            self.depth -= 1
            if self.depth == 0 and self.restore is not None:
                self.restore()
                self.restore = None

    return CompileListener


def show_compiling():
    """Show :data:`COMPILING` on the innermost live bar, else on a status line; returns
    the function that takes it away."""
    if LIVE_BARS:
        bar, task, description = LIVE_BARS[-1]
        bar.update(task, description=f"{description} · {COMPILING}")
        return lambda: bar.update(task, description=description)
    from rich.console import Console

    status = Console(stderr=True).status(COMPILING)
    status.start()
    return status.stop
