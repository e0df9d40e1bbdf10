"""Commands every family shares: ``run``, ``validate`` and ``sweep``.

Each command calls the public Python API only (:func:`robofleet.load_scenario`,
:func:`robofleet.simulate`, :func:`robofleet.experiments.run_sweep`). Heavy modules are
imported inside the commands so that ``robofleet --help`` stays fast.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Annotated, Any, Optional

import typer
from rich.console import Console
from rich.table import Table

from ..core.errors import RobofleetError

# the options every sweep-running command shares (``sweep`` and each ``reproduce``)
ExecutorOption = Annotated[str, typer.Option(help="Where the runs execute: serial, process (local worker processes) or dask.")]
SchedulerOption = Annotated[Optional[str], typer.Option(help="Dask scheduler address, e.g. tcp://host:8786 (default: a local cluster).")]
WorkersOption = Annotated[Optional[int], typer.Option(min=1, help="Local worker processes (default: available CPUs).")]


def load_family(scenario: Path, family: str):
    """Load ``scenario`` and insist it belongs to ``family`` (one-line error otherwise)."""
    from .. import load_scenario
    from ..core.errors import ScenarioError

    spec = load_scenario(scenario)
    if spec.family != family:
        raise ScenarioError("family", family, spec.family, source=str(scenario))
    return spec

MIN_TABLE_COLUMNS = 3  # value columns shown however narrow the terminal
COLUMN_WIDTH = 11  # characters a numeric column needs to stay readable
PREFERRED_COLUMNS = ("success", "collisions", "min_pair_distance", "makespan", "mean_travel_time")


def register(app: typer.Typer, reproduce: typer.Typer) -> None:
    """Add ``run``, ``validate`` and ``sweep`` to the main ``app``."""
    app.command("run")(run_command)
    app.command("validate")(validate_command)
    app.command("sweep")(sweep_command)


def run_command(
    scenario: Annotated[Path, typer.Argument(help="Scenario YAML file.")],
    seed: Annotated[int, typer.Option(min=0, help="Seed of every random draw of the run.")] = 0,
    out: Annotated[Optional[Path], typer.Option(help="Output directory (default: runs/<scenario>-seed<S>).")] = None,
    animate: Annotated[bool, typer.Option("--animate", help="Also write animation.gif.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar and no summary table.")] = False,
) -> None:
    """Simulate a scenario; write trace.npz/trace.json, summary.json and optionally animation.gif."""
    from .. import load_scenario, simulate
    from ..core.trace import dumps_json

    spec = load_scenario(scenario)
    out_dir = out if out is not None else Path("runs") / f"{scenario.stem}-seed{seed}"
    trace = simulate(spec, seed=seed, progress=not quiet)
    trace.save(out_dir)
    summary = trace.summary()
    (out_dir / "summary.json").write_text(dumps_json(summary) + "\n")
    written = ["trace.npz", "trace.json", "summary.json"]
    if not quiet:
        Console().print(key_value_table(summary, f"{scenario.name} ({spec.family}, seed {seed})"))
    if animate:
        animate_trace = family_animation(spec.family)
        animate_trace(trace, out_dir / "animation.gif")
        written.append("animation.gif")
    typer.echo(f"wrote {out_dir}/ {{{', '.join(written)}}}")


def family_animation(family: str):
    """``robofleet.viz.<family>.animate_trace``, or a one-line error if there is none."""
    module_name = f"robofleet.viz.{family}"
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name != module_name:
            raise
        raise RobofleetError(f"--animate: expected an animation for family {family!r}, received none (no module {module_name})") from None
    animate_trace = getattr(module, "animate_trace", None)
    if not callable(animate_trace):
        raise RobofleetError(f"--animate: expected an animation for family {family!r}, received none ({module_name} has no animate_trace)")
    return animate_trace


def validate_command(scenario: Annotated[Path, typer.Argument(help="Scenario YAML file.")]) -> None:
    """Check a scenario file without running it."""
    from .. import load_scenario

    spec = load_scenario(scenario)
    typer.echo(f"ok: {scenario} ({spec.family})")


def sweep_command(
    sweep: Annotated[Path, typer.Argument(help="Sweep YAML file (scenario × grid × seeds).")],
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    out: Annotated[Optional[Path], typer.Option(help="Result store directory (default: the sweep's out, else results/<sweep>).")] = None,
) -> None:
    """Run a sweep, resuming from its result store; print the means per parameter combination."""
    from ..experiments import run_sweep, summarize_sweep

    frame = run_sweep(sweep, executor=executor, scheduler=scheduler, progress=True, workers=workers, out=out)
    failed = int(frame["error"].notna().sum())
    typer.echo(f"results: {frame.attrs['store']}/ ({frame['run_id'].nunique()} runs, {failed} failed)")
    if frame.attrs.get("other_rows"):
        typer.echo(f"note: the store also holds {frame.attrs['other_rows']} rows of other sweeps (not shown)")
    means = summarize_sweep(frame)
    leading = list(means.columns[: len(frame.attrs["grid"]) + 2])
    values = [c for c in means.columns if c not in leading]
    values = [c for c in PREFERRED_COLUMNS if c in values] + [c for c in values if c not in PREFERRED_COLUMNS]
    console = Console()
    fits = max(MIN_TABLE_COLUMNS, console.width // COLUMN_WIDTH - len(leading))
    console.print(frame_table(means[leading + values], "means per parameter combination", leading=len(leading), values=fits))
    if failed:
        first = frame.loc[frame["error"].notna(), ["run_id", "error"]].iloc[0]
        typer.echo(f"first failure: run {first['run_id']}: {first['error']}")


def format_value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def key_value_table(mapping: dict, title: str) -> Table:
    table = Table(title=title)
    table.add_column("metric")
    table.add_column("value", justify="right")
    for key, value in mapping.items():
        table.add_row(str(key), format_value(value))
    return table


def frame_table(frame, title: str, leading: int = 0, values: int = MIN_TABLE_COLUMNS) -> Table:
    """A rich table of a small DataFrame: its first ``leading`` columns (grid values,
    counts) and at most ``values`` more."""
    columns = list(frame.columns)
    shown = columns[: leading + values]
    note = "" if len(shown) == len(columns) else f" ({len(shown)} of {len(columns)} columns; all in the store)"
    table = Table(title=title + note)
    for column in shown:
        table.add_column(str(column), justify="right", overflow="fold")
    for row in frame[shown].itertuples(index=False):
        table.add_row(*(format_value(v) for v in row))
    return table
