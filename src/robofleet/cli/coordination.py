"""Commands of the coordination family (paper 000): ``check`` and ``reproduce rmtrack``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import ExecutorOption, SchedulerOption, WorkersOption, load_family

from ..core.errors import ConfigError

MAX_LISTED = 10


def register(app: typer.Typer, reproduce: typer.Typer) -> None:
    """Add ``robofleet check`` and ``robofleet reproduce rmtrack``."""
    app.command("check")(check_command)
    reproduce.command("rmtrack")(reproduce_rmtrack)


def check_command(scenario: Annotated[Path, typer.Argument(help="Coordination scenario YAML file.")]) -> None:
    """Report whether a scenario's trajectories are non-conflicting (Definition 4) and whether
    their collision segments are disjoint (Theorem 4: then no flip can deadlock)."""
    from ..coordination.scenario import check

    spec = load_family(scenario, "coordination")
    traj, space, report = check(spec)
    typer.echo(f"{scenario}: {traj.n_robots} robots, {space.n_obstacles} coordination-space obstacles, "
               f"longest trajectory {int(traj.lengths.max())} steps")
    if report.non_conflicting:
        typer.echo("non-conflicting (Definition 4): yes — deadlock ⇔ cycle in the active segment graph")
    else:
        typer.echo(f"non-conflicting (Definition 4): no — {len(report.conflicts)} conflicts")
        for c in report.conflicts[:MAX_LISTED]:
            typer.echo(f"  robot {c.robot} at step {c.step} is within 2r of the {c.which} of robot {c.other}")
    if report.disjoint_segments:
        typer.echo("disjoint collision segments (Theorem 4): yes — no flip can deadlock")
    else:
        typer.echo(f"disjoint collision segments (Theorem 4): no — {len(report.overlaps)} overlaps")
        for o in report.overlaps[:MAX_LISTED]:
            typer.echo(f"  robot {o.robot}: steps {o.first[0]}..{o.first[1]} (with robot {o.others[0]}) and "
                       f"{o.second[0]}..{o.second[1]} (with robot {o.others[1]})")


def reproduce_rmtrack(
    instances: Annotated[int, typer.Option(min=1, help="Random instances per robot count.")] = 10,
    robots: Annotated[str, typer.Option(help="Comma-separated robot counts.")] = "5,10,15,20",
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("results/rmtrack"),
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    seed: Annotated[int, typer.Option(min=0, help="Root seed of the instances and disturbances.")] = 0,
    base_probability: Annotated[float, typer.Option(min=0.0, max=0.999, help="Disturbance probability outside the region.")] = 0.05,
    animate: Annotated[bool, typer.Option("--animate/--no-animate", help="Also animate one run with the largest robot count.")] = True,
) -> None:
    """Fig. 6 of paper 000: six variants on the same plans and disturbances; plots + table.md."""
    from ..coordination.reproduce import example_trace, markdown_table, run_reproduction, summarize
    from ..viz.coordination import animate_trace, plot_fig6, plot_plan

    counts = _robot_counts(robots)
    rows = run_reproduction(out, instances, counts, executor=executor, scheduler=scheduler, workers=workers,
                            root_seed=seed, base_probability=base_probability)
    summary = summarize(rows)
    summary.to_csv(out / "summary.csv", index=False)
    (out / "table.md").write_text(markdown_table(summary))
    plot_fig6(summary, out / "fig6.png")
    written = ["runs/", "summary.csv", "table.md", "fig6.png"]
    if animate:
        trace = example_trace(max(counts), instance_seed=seed + 1, seed=seed + 1)
        trace.save(out / "example")
        plot_plan(trace, out / "plan.png")
        animate_trace(trace, out / "animation.gif")
        written += ["example/", "plan.png", "animation.gif"]
    failed = int(rows["error"].notna().sum()) if "error" in rows else 0
    typer.echo(markdown_table(summary))
    typer.echo(f"wrote {out}/ {{{', '.join(written)}}}" + (f"; {failed} failed tasks" if failed else ""))


def _robot_counts(text: str) -> list[int]:
    try:
        counts = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1:
        raise ConfigError(f"--robots: expected comma-separated positive integers, received {text!r}")
    return counts
