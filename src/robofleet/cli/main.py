"""The ``robofleet`` command line: generic commands over the family table.

Thin by design: every command calls the public Python API (:func:`robofleet.load_scenario`,
:func:`robofleet.simulate`, a family's ``check``, :func:`robofleet.experiments.run_sweep`,
:func:`robofleet.experiments.reproduce`), and every family gets every command.
Anything a user can get wrong ends as one line on stderr and exit status 2.
"""

from __future__ import annotations

import os
import sys
import warnings
from contextlib import contextmanager
from importlib.metadata import version as installed_version
from pathlib import Path
from typing import Annotated, Iterator, Optional

import pandas as pd
import typer
from rich.console import Console

from ..core.budget import MEMORY_BUDGET_VARIABLE, parse_size
from ..core.config import read_mapping
from ..core.errors import ConfigError, Interrupted, RobofleetError, short_repr
from ..core.rng import resolve_seed
from ..core.trace import dumps_json
from ..experiments import reproduce as run_reproduction
from ..experiments import plan_sweep, run_sweep, summarize_sweep
from ..experiments.reproductions import REPRODUCTIONS
from ..ros2.cli import export_command, ros2_app
from ..scenarios import FAMILIES, catalogue, family_of, load_scenario, simulate
from ..viz.replay.building import MAX_FRAMES
from .display import COLUMN_WIDTH, MIN_TABLE_COLUMNS, PREFERRED_COLUMNS, frame_table, key_value_table

INTERRUPTED = 130  # the exit status of a process stopped by Ctrl-C (128 + SIGINT)
PAPERS = "; ".join(f"{f.name}: {f.paper}" for f in FAMILIES.values())
app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help=f"Decentralized multi-robot coordination, one family per paper ({PAPERS}).")

# the options every command that runs work shares
ScenarioArgument = Annotated[str, typer.Argument(help="Scenario: a YAML file or a shipped name such as avoidance/circle_swap (see `robofleet scenarios`).")]
OutOption = Annotated[Optional[Path], typer.Option(help="Output directory.")]
ExecutorOption = Annotated[str, typer.Option(help="Where the runs execute: serial, process (local worker processes) or dask.")]
SchedulerOption = Annotated[Optional[str], typer.Option(help="Dask scheduler address, e.g. tcp://host:8786 (default: a local cluster).")]
WorkersOption = Annotated[Optional[int], typer.Option(min=1, help="Local worker processes (default: available CPUs).")]
QuietOption = Annotated[bool, typer.Option("--quiet", help="No progress bar and no result table.")]
MemoryBudgetOption = Annotated[Optional[str], typer.Option(
    "--memory-budget", help=f"Refuse runs whose arrays would need more, e.g. 8GiB (default: ${MEMORY_BUDGET_VARIABLE}, else 4GiB).")]


class Stopped(Exception):
    """Ctrl-C during a sweep or reproduction, carried past typer (which would turn a
    ``KeyboardInterrupt`` into a silent exit code) to :func:`main`."""


@contextmanager
def resumable() -> Iterator[None]:
    """Turn the sweep machinery's :class:`~robofleet.core.errors.Interrupted` into :class:`Stopped`."""
    try:
        yield
    except Interrupted as exc:
        raise Stopped(str(exc)) from None


def version_callback(value: bool) -> None:
    if value:
        typer.echo(f"robofleet {installed_version('robofleet')}")
        raise typer.Exit()


@app.callback()
def root(version: Annotated[bool, typer.Option("--version", callback=version_callback, is_eager=True, help="Print the version and exit.")] = False) -> None:
    """Decentralized multi-robot coordination."""


@app.command("run")
def run_command(
    scenario: ScenarioArgument,
    seed: Annotated[Optional[int], typer.Option(min=0, help="Seed of every random draw (default: a fresh one, printed so the run can be replayed).")] = None,
    out: OutOption = None,
    animate: Annotated[bool, typer.Option("--animate", help="Also write animation.gif.")] = False,
    plot: Annotated[bool, typer.Option("--plot", help="Also write plot.png.")] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an earlier run's files in --out.")] = False,
    quiet: QuietOption = False,
    memory_budget: MemoryBudgetOption = None,
) -> None:
    """Simulate a scenario; write trace.npz, trace.json, summary.json (and plot.png, animation.gif)."""
    use_memory_budget(memory_budget)
    if is_sweep(scenario):
        raise ConfigError(f"SCENARIO: expected a scenario file, received the sweep {scenario} (run it with `robofleet sweep`)")
    spec = load_scenario(scenario)
    family = family_of(spec)
    seed = resolve_seed(seed, "--seed")
    out_dir = out if out is not None else Path("runs") / f"{spec.scenario_name or family.name}-seed{seed}"
    prepare_run_directory(out_dir, overwrite)
    trace = simulate(spec, seed=seed, progress=not quiet)
    trace.save(out_dir)
    summary = trace.summary()
    (out_dir / "summary.json").write_text(dumps_json(summary) + "\n")
    written = ["trace.npz", "trace.json", "summary.json"]
    if not quiet:
        Console().print(key_value_table(summary, f"{spec.scenario_name} ({family.name}, seed {trace.seed})"))
    if plot:
        family.viz_module().plot_trace(trace, out_dir / "plot.png")
        written.append("plot.png")
    if animate:
        family.viz_module().animate_trace(trace, out_dir / "animation.gif")
        written.append("animation.gif")
    typer.echo(f"wrote {out_dir}/ {{{', '.join(written)}}} (seed {trace.seed})")


RUN_FILES = ("trace.npz", "trace.json", "summary.json", "plot.png", "animation.gif")


def prepare_run_directory(out_dir: Path, overwrite: bool) -> None:
    """Make ``out_dir`` ready for a run's files, before anything is computed.

    A non-empty directory is refused unless ``overwrite``, which removes the files an
    earlier run wrote (:data:`RUN_FILES`) and nothing else.

    Raises
    ------
    ConfigError
        ``--out`` is a file or lies under one, is not writable, or holds files without ``--overwrite``.
    """
    try:
        blocking = next((p for p in (out_dir, *out_dir.parents) if p.exists() and not p.is_dir()), None)
        present = sorted(p.name for p in out_dir.iterdir()) if out_dir.is_dir() and blocking is None else []
    except (OSError, ValueError) as exc:  # a name too long, a NUL byte, no permission
        raise ConfigError(f"--out: expected a usable directory path, received {short_repr(str(out_dir))} "
                          f"({getattr(exc, 'strerror', None) or exc})") from None
    if blocking is not None:
        raise ConfigError(f"--out: expected a directory, received {out_dir} ({blocking} is a file)")
    if present and not overwrite:
        shown = ", ".join(present[:4]) + (", ..." if len(present) > 4 else "")
        raise ConfigError(f"--out: expected a new or empty directory (or --overwrite), received {out_dir}, which holds {shown}")
    for name in RUN_FILES:
        (out_dir / name).unlink(missing_ok=True)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / f".write-test-{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError as exc:
        raise ConfigError(f"--out: expected a writable directory, received {out_dir} ({exc.strerror})") from None


@app.command("validate")
def validate_command(scenario: Annotated[str, typer.Argument(help="A scenario or sweep: a YAML file or a shipped name.")],
                     memory_budget: MemoryBudgetOption = None) -> None:
    """Check a scenario (or a sweep, every grid point of it) without running it: everything a run would read."""
    use_memory_budget(memory_budget)
    if is_sweep(scenario):
        plan = plan_sweep(scenario)
        typer.echo(f"ok: {plan.source or scenario} (sweep: {len(plan.combinations)} grid points × {len(plan.seeds)} seeds = {len(plan.tasks)} runs)")
        return
    spec = load_scenario(scenario)
    typer.echo(f"ok: {spec.source or scenario} ({spec.family})")


def is_sweep(ref: str) -> bool:
    """Whether ``ref`` names a sweep: a YAML file with a top-level ``scenario`` key and no
    ``family`` key, or a shipped sweep name that is no scenario name."""
    path = Path(ref)
    if catalogue.is_file(path):
        try:
            data = read_mapping(path)[0]
        except RobofleetError:
            return False  # loading it as a scenario reports what is wrong
        return "scenario" in data and "family" not in data
    return not catalogue.is_file(path, exists=True) and is_shipped(ref, "sweeps") and not is_shipped(ref, "scenarios")


def is_shipped(name: str, kind: str) -> bool:
    """Whether ``name`` is a shipped scenario (or sweep) name."""
    try:
        catalogue.path(name, kind)
    except RobofleetError:
        return False
    return True


def use_memory_budget(size: str | None) -> None:
    """Apply ``--memory-budget`` for this command (and the worker processes it starts)."""
    if size is not None:
        os.environ[MEMORY_BUDGET_VARIABLE] = str(parse_size(size, "--memory-budget"))


@app.command("check")
def check_command(scenario: ScenarioArgument) -> None:
    """Report which of its paper's checkable conditions a scenario meets, and what follows."""
    spec = load_scenario(scenario)
    family = family_of(spec)
    typer.echo(f"{spec.source or scenario}: {family.title} — {family.paper}")
    for guarantee in family.check(spec):
        typer.echo(guarantee.line())


@app.command("search-check", hidden=True)
def search_check_alias(scenario: ScenarioArgument) -> None:
    """Earlier spelling of ``check`` for search scenarios."""
    check_command(scenario)


@app.command("flocking-check", hidden=True)
def flocking_check_alias(scenario: ScenarioArgument) -> None:
    """Earlier spelling of ``check`` for flocking scenarios."""
    check_command(scenario)


app.add_typer(ros2_app, name="ros2")  # robofleet ros2 sim | filter | supervisor | launch (ros2 extra)
app.command("export")(export_command)


@app.command("scenarios")
def scenarios_command(
    family: Annotated[Optional[str], typer.Option(help="Only this family's scenarios.")] = None,
    sweeps: Annotated[bool, typer.Option("--sweeps", help="List the shipped sweeps instead.")] = False,
) -> None:
    """List the shipped scenarios (name, family, description); every command takes these names."""
    if family is not None and family not in FAMILIES:
        raise RobofleetError(f"--family: expected one of {sorted(FAMILIES)}, received {family!r}")
    entries = [e for e in catalogue.list("sweeps" if sweeps else "scenarios") if family is None or e.family == family]
    width = max((len(e.name) for e in entries), default=0)
    for entry in entries:
        typer.echo(f"{entry.name:<{width}}  {entry.family:<12}  {entry.description}")


@app.command("sweep")
def sweep_command(
    sweep: Annotated[str, typer.Argument(help="Sweep: a YAML file (scenario × grid × seeds) or a shipped name (see `robofleet scenarios --sweeps`).")],
    out: Annotated[Optional[Path], typer.Option(help="Result store directory (default: the sweep's out, else results/<sweep>).")] = None,
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    quiet: QuietOption = False,
    memory_budget: MemoryBudgetOption = None,
) -> None:
    """Run a sweep, resuming from its result store; print the means per parameter combination."""
    use_memory_budget(memory_budget)
    with resumable():
        frame = run_sweep(sweep, executor=executor, scheduler=scheduler, progress=not quiet, workers=workers, out=out)
    failed = int(frame["error"].notna().sum())
    typer.echo(f"results: {frame.attrs['store']}/ ({frame['run_id'].nunique()} runs, {failed} failed)")
    if frame.attrs.get("other_rows"):
        typer.echo(f"note: the store also holds {frame.attrs['other_rows']} rows of other sweeps (not shown)")
    if not quiet:
        print_means(frame)
    if failed:
        first = frame.loc[frame["error"].notna(), ["run_id", "error"]].iloc[0]
        typer.echo(f"first failure: run {first['run_id']}: {first['error']}")


def print_means(frame: pd.DataFrame) -> None:
    """The sweep's means per grid combination, the headline columns first."""
    means = summarize_sweep(frame)
    leading = list(means.columns[: len(frame.attrs["grid"]) + 2])
    values = [c for c in means.columns if c not in leading]
    values = [c for c in PREFERRED_COLUMNS if c in values] + [c for c in values if c not in PREFERRED_COLUMNS]
    console = Console()
    fits = max(MIN_TABLE_COLUMNS, console.width // COLUMN_WIDTH - len(leading))
    console.print(frame_table(means[leading + values], "means per parameter combination", leading=len(leading), values=fits))


REPRODUCE_HELP = "Reproduce a paper's experiment: sweeps, summary.csv, table.md and figures. NAME is one of: " + "; ".join(
    f"{r.name} ({r.paper})" for r in REPRODUCTIONS.values())


@app.command("reproduce", help=REPRODUCE_HELP)
def reproduce_command(
    name: Annotated[str, typer.Argument(help="The experiment: " + ", ".join(REPRODUCTIONS) + ".")],
    out: OutOption = None,
    seeds: Annotated[Optional[int], typer.Option(min=1, help="Seeds per grid point (overrides the budget's).")] = None,
    budget: Annotated[str, typer.Option(help="How much to run: smallest (a smoke run), default, or full (the paper's size).")] = "default",
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    quiet: QuietOption = False,
) -> None:
    if name not in REPRODUCTIONS:
        raise RobofleetError(f"reproduce: NAME: expected one of {sorted(REPRODUCTIONS)}, received {name!r}")
    declaration = REPRODUCTIONS[name]
    out_dir = out if out is not None else Path("results") / name
    with resumable():
        result = run_reproduction(declaration, out_dir, budget=budget, seeds=seeds, executor=executor, scheduler=scheduler,
                                  workers=workers, progress=not quiet)
    if not quiet:
        typer.echo(result.markdown)
    failed = f"; {result.failed} failed runs (their errors are in the runs store)" if result.failed else ""
    typer.echo(f"wrote {out_dir}/ {{runs/, {', '.join(p.name for p in result.files)}}}{failed}")


@app.command("view")
def view_command(
    run: Annotated[Path, typer.Argument(help="A run directory (or its trace.json / trace.npz), or a reproduction's output directory.")],
    out: Annotated[Path | None, typer.Option(help="The HTML file (default: RUN/replay.html, or RUN/report.html for a reproduction).")] = None,
    rerun: Annotated[Path | None, typer.Option("--rerun", help="Also write a recording for the Rerun viewer (FILE.rrd; needs the rerun extra).")] = None,
    no_open: Annotated[bool, typer.Option("--no-open", help="Only write the file; do not open a browser.")] = False,
    max_frames: Annotated[int, typer.Option(min=2, help="Frames of the replay at most (longer runs show evenly spaced states).")] = MAX_FRAMES,
) -> None:
    """Write a self-contained HTML replay of a run (or one report of a reproduction) and open it."""
    from ..core.trace import Trace
    from ..viz.replay.page import open_in_browser, write_html
    from ..viz.replay.report import write_report
    from ..viz.replay.target import locate

    target = locate(run)
    page = out if out is not None else target.default_output()
    if rerun is not None and (target.kind != "run" or rerun.suffix != ".rrd"):
        raise ConfigError(f"--rerun: expected a FILE.rrd for a run directory, received {rerun} for {target.kind} {target.directory}")
    if target.kind == "reproduction":
        write_report(target.directory, page)
        written = [page]
    else:
        scene = replay_scene_of(Trace.load(target.directory), target.directory, max_frames)
        written = []
        if rerun is not None:
            from ..viz.replay.rerun_export import write_rrd

            written.append(write_rrd(scene, rerun))
        written.insert(0, write_html(scene, page))
    typer.echo("wrote " + ", ".join(str(p) for p in written))
    if not no_open and not open_in_browser(page):
        typer.echo(f"no browser to open here; open {page.resolve().as_uri()}")


def replay_scene_of(trace, directory: Path, max_frames: int):
    """The replay scene of a loaded trace, built by its family's replay module."""
    from ..viz.replay import scene_builder

    if trace.family not in FAMILIES:
        raise ConfigError(f"{directory / 'trace.json'}: family: expected one of {sorted(FAMILIES)}, received {trace.family!r}")
    try:
        return scene_builder(trace.family)(trace, max_frames=max_frames)
    except KeyError as exc:
        raise ConfigError(f"{directory}: expected a complete {trace.family} trace, received one without {exc}") from None


def show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int, file: object = None,
                 line: str | None = None) -> None:
    """Warnings (a damaged store file set aside, ...) as one line each, without source lines."""
    typer.echo(f"warning: {message}", err=True)


def usage_error_line(exc: Exception, argv: list[str]) -> str:
    """A command-line usage error as one line: click's message, the value received when the
    error names an option that was given one, and where to read the usage."""
    line = " ".join(exc.format_message().split())
    param = getattr(exc, "param", None)
    received = option_value(argv, getattr(param, "opts", None) or [])
    if received is not None and "received" not in line:
        line += f", received {received!r}"
    command = getattr(getattr(exc, "ctx", None), "command_path", None) or "robofleet"
    return f"{line} (see '{command} --help')"


def option_value(argv: list[str], names: list[str]) -> str | None:
    """The text given to the first of ``names`` on ``argv`` (``--opt value`` or ``--opt=value``)."""
    for i, token in enumerate(argv):
        for name in names:
            if token == name and i + 1 < len(argv):
                return argv[i + 1]
            if token.startswith(name + "="):
                return token[len(name) + 1:]
    return None


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning robofleet errors into one line and exit status 2."""
    warnings.showwarning = show_warning
    budget = os.environ.get(MEMORY_BUDGET_VARIABLE)
    try:
        code = app(args=argv, standalone_mode=False)
    except Stopped as exc:
        typer.echo(str(exc), err=True)
        sys.exit(INTERRUPTED)
    except RobofleetError as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("interrupted; finished results are kept", err=True)
        sys.exit(INTERRUPTED)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except Exception as exc:
        # usage errors: typer raises its own copies of click's exception classes, so they
        # are recognised by what they can do (show themselves, carry an exit code)
        message, code = getattr(exc, "format_message", None), getattr(exc, "exit_code", None)
        if type(exc).__name__ == "NoArgsIsHelpError":  # bare `robofleet`: the help, as usual
            exc.show()
            sys.exit(code)
        if callable(message) and isinstance(code, int):
            typer.echo(f"error: {usage_error_line(exc, argv if argv is not None else sys.argv[1:])}", err=True)
            sys.exit(code)
        raise
    finally:  # --memory-budget holds for one command, also when main() is called in-process
        if budget is None:
            os.environ.pop(MEMORY_BUDGET_VARIABLE, None)
        else:
            os.environ[MEMORY_BUDGET_VARIABLE] = budget
    if code == INTERRUPTED:  # typer's answer to Ctrl-C outside a sweep
        typer.echo("interrupted; nothing of the interrupted run was written", err=True)
    if isinstance(code, int) and code:
        sys.exit(code)


if __name__ == "__main__":
    main()
