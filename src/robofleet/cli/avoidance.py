"""``robofleet reproduce buavc``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import ExecutorOption, SchedulerOption, WorkersOption


def register(app: typer.Typer, reproduce: typer.Typer) -> None:
    reproduce.command("buavc")(reproduce_buavc)


def reproduce_buavc(
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("results/buavc"),
    seeds: Annotated[int, typer.Option(min=1, help="Seeds per method and noise level.")] = 20,
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
) -> None:
    """Monte Carlo of B-UAVC vs BVC vs inflated BVC over seeds, noise levels and δ."""
    from ..avoidance.reproduce import reproduce

    result = reproduce(out, seeds=seeds, executor=executor, scheduler=scheduler, workers=workers)
    typer.echo(result["table"].read_text())
    typer.echo(f"wrote {result['table']} and {result['figure']}")
