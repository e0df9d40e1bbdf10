"""CLI of the ``search`` family (paper 002).

* ``robofleet reproduce search [--runs N] [--out DIR] [--executor ...] [--scheduler ADDR]``:
  the Fig. 7 sweep and the coverage study, with plots and ``table.md``.
* ``robofleet search-check SCENARIO``: which of the paper's assumptions hold for a scenario
  and what the completeness guarantee then means.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import ExecutorOption, SchedulerOption, WorkersOption, load_family


def register(app: typer.Typer, reproduce: typer.Typer) -> None:
    """Add ``reproduce search`` and ``search-check``."""
    reproduce.command("search")(reproduce_search_command)
    app.command("search-check")(search_check_command)


def reproduce_search_command(
    runs: Annotated[int, typer.Option(min=2, help="Runs per point of Fig. 7 (the paper: 500).")] = 500,
    coverage_runs: Annotated[int, typer.Option(min=2, help="Runs per grid and robot count of the coverage study.")] = 50,
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("results/search"),
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress bars.")] = False,
) -> None:
    """Reproduce Fig. 7 of paper 002 (four algorithms, 1–13 robots) and the grid coverage study."""
    from .. import load_scenario, simulate
    from ..scenarios import shipped_scenario
    from ..search.reproduce import reproduce_search
    from ..viz import search as viz

    result = reproduce_search(out, runs, coverage_runs, executor=executor, scheduler=scheduler, workers=workers,
                              progress=not quiet)
    written = [viz.plot_fig7(result["fig7"], out / "fig7.png"), viz.plot_coverage_ranges(result["coverage"], out / "coverage.png")]
    trace = simulate(load_scenario(shipped_scenario("search", "fig7.yaml"), {"robots.count": 3}), seed=5)
    trace.save(out / "fig5_trace")
    written.append(viz.plot_routes(trace, out / "fig5_routes.png"))
    written.append(viz.plot_routes(trace, out / "fig6_route.png", robots=[0], title="Route of robot 0"))
    typer.echo(Path(result["table"]).read_text())
    typer.echo(f"wrote {out}/ {{table.md, fig7_runs/, coverage_runs/, " + ", ".join(p.name for p in written) + "}")


def search_check_command(scenario: Annotated[Path, typer.Argument(help="Scenario YAML file of family search.")]) -> None:
    """Report which of Assumptions 2.4, 2.5, 3.1.1–3.1.3 hold and what Theorem 4.1 then guarantees."""

    spec = load_family(scenario, "search")
    report = spec.assumption_report()
    for c in report.checks:
        typer.echo(f"{'holds ' if c.holds else 'FAILS '} {c.name:<6} {c.statement}: {c.value:.4g} vs {c.required:.4g}")
    typer.echo(f"grid: {report.grid_kind.value}")
    typer.echo(report.guarantee)
