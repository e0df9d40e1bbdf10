"""A progress bar for long loops (rich), silent when disabled or not on a terminal."""

from __future__ import annotations

from contextlib import contextmanager
from typing import Iterator

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


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
        yield lambda n=1: bar.advance(task, n)
        bar.update(task, total=bar.tasks[0].completed)
