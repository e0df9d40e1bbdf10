"""``robofleet reproduce buavc-models``: B-UAVC for every robot model of paper 003."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import ExecutorOption, SchedulerOption, WorkersOption


def register(app: typer.Typer, reproduce: typer.Typer) -> None:
    reproduce.command("buavc-models")(reproduce_buavc_models)


def reproduce_buavc_models(
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("results/buavc-models"),
    seeds: Annotated[int, typer.Option(min=1, help="Seeds per model, method and noise level (quadrotor and mixed teams use a fifth).")] = 10,
    models: Annotated[str, typer.Option(help="Comma-separated subset of: single_integrator, double_integrator, diff_drive, quadrotor, heterogeneous.")] = "",
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    animate: Annotated[bool, typer.Option(help="Write the diff-drive and quadrotor GIFs.")] = True,
) -> None:
    """Monte Carlo per robot model: B-UAVC vs BVC vs inflated BVC (vs ORCA for single integrators) over seeds, σ and δ."""
    from ..avoidance.reproduce_models import MODELS, reproduce
    from ..core.errors import ScenarioError

    chosen = tuple(m.strip() for m in models.split(",") if m.strip()) or tuple(MODELS)
    unknown = [m for m in chosen if m not in MODELS]
    if unknown:
        raise ScenarioError("--models", f"names from {list(MODELS)}", ",".join(unknown))
    result = reproduce(out, seeds=seeds, executor=executor, scheduler=scheduler, workers=workers, models=chosen, animate=animate)
    typer.echo(result["table"].read_text())
    typer.echo(f"wrote {result['table']}, {', '.join(map(str, result['figures']))}" + (f", {', '.join(map(str, result['gifs']))}" if result["gifs"] else ""))
