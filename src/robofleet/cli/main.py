"""The ``robofleet`` command line: generic commands over the family table.

Thin by design: every command calls the public Python API (:func:`robofleet.load_scenario`,
:func:`robofleet.simulate`, a family's ``check``, :func:`robofleet.experiments.run_sweep`,
:func:`robofleet.experiments.reproduce`), and every family gets every command.
Anything a user can get wrong ends as one line on stderr and exit status 2.
"""

from __future__ import annotations

import functools
import os
import sys
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Iterator, Optional

import typer
import typer.main
from typer.core import TyperCommand, TyperGroup

from ..core.budget import MEMORY_BUDGET_VARIABLE, parse_size
from ..core.errors import ConfigError, Interrupted, RobofleetError, one_line, short_repr
from ..core.files import Staging, is_temporary, staged_files, write_text
from ..ros2.cli import export_command, ros2_app
from ..scenarios import FAMILIES, catalogue, family_of, load_scenario, simulate
from ..viz.replay import MAX_FRAMES

if TYPE_CHECKING:  # the commands import what they use when they run: `robofleet --help` loads no numerical library
    import pandas as pd

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
SET_HELP = ("Override a scenario field: KEY=VALUE with KEY a dotted field path (robots.n=8, max_steps=200, teams.0.sigma=0.05) "
            "and VALUE in YAML (a number, a word, [a, list]); repeatable; checked as the file is.")
SetOption = Annotated[Optional[list[str]], typer.Option("--set", metavar="KEY=VALUE", help=SET_HELP, show_default=False)]


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
        from importlib.metadata import version as installed_version

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
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an earlier run's files in --out, once the new run is complete.")] = False,
    quiet: QuietOption = False,
    memory_budget: MemoryBudgetOption = None,
    assignments: SetOption = None,
) -> None:
    """Simulate a scenario; write trace.npz, trace.json, summary.json (and plot.png, animation.gif).

    The run's files replace an earlier run's (:data:`RUN_FILES`) together, once all three
    are complete (:func:`~robofleet.core.files.staged_files`); the figures follow, each
    replacing nothing until complete. Ctrl-C at any moment leaves the earlier run or the
    new one, and its line names the files on disk (:func:`what_is_on_disk`).
    """
    from rich.console import Console

    from ..core.rng import resolve_seed
    from ..core.trace import dumps_json
    from .display import key_value_table

    use_memory_budget(memory_budget)
    if is_sweep(scenario):
        raise ConfigError(f"SCENARIO: expected a scenario file, received the sweep {scenario} (run it with `robofleet sweep`)")
    spec = scenario_with(scenario, assignments)
    family = family_of(spec)
    seed = resolve_seed(seed, "--seed")
    out_dir = out if out is not None else Path("runs") / f"{spec.scenario_name or family.name}-seed{seed}"
    check_run_directory(out_dir, overwrite)
    wanted = [*RUN_FILES[:3], *(["plot.png"] if plot else []), *(["animation.gif"] if animate else [])]
    staging = None
    try:
        trace = simulate(spec, seed=seed, progress=not quiet)
        summary = trace.summary()
        with staged_files(out_dir, RUN_FILES) as staging:
            trace.save(staging.path)
            write_text(staging.path / "summary.json", dumps_json(summary) + "\n")
        if not quiet:
            Console().print(key_value_table(summary, f"{spec.scenario_name} ({family.name}, seed {trace.seed})"))
        if plot:
            family.viz_module().plot_trace(trace, out_dir / "plot.png")
        if animate:
            family.viz_module().animate_trace(trace, out_dir / "animation.gif")
    except KeyboardInterrupt:
        raise Stopped(f"interrupted; {what_is_on_disk(out_dir, staging, seed, wanted)}") from None
    except OSError as exc:  # a full disk, a folder made read-only meanwhile
        raise ConfigError(f"--out: expected a writable directory, received {out_dir} ({exc.strerror or exc}); "
                          f"{what_is_on_disk(out_dir, staging, seed, wanted)}") from None
    typer.echo(f"wrote {out_dir}/ {{{', '.join(wanted)}}} (seed {trace.seed})")


RUN_FILES = ("trace.npz", "trace.json", "summary.json", "plot.png", "animation.gif")
"""The files of a run: a new run replaces all of an earlier run's (and no other file)."""


def what_is_on_disk(out_dir: Path, staging: Staging | None, seed: int, wanted: list[str]) -> str:
    """Which run a stopped ``robofleet run`` left in ``out_dir`` (the earlier one or the new
    one, as ``staging`` tells) and exactly which of its files are there."""
    present = [name for name in RUN_FILES if (out_dir / name).is_file()]
    if staging is not None and staging.moved:
        missing = [name for name in wanted if name not in present]
        return f"{out_dir}/ holds the new run (seed {seed}): {', '.join(present)}" + (f" ({', '.join(missing)} not written)" if missing else "")
    if present:
        return f"the new run was not written; {out_dir}/ holds the earlier run's files, unchanged: {', '.join(present)}"
    return f"nothing was written ({out_dir} {'holds no run files' if out_dir.is_dir() else 'was not created'})"


def check_run_directory(out_dir: Path, overwrite: bool) -> None:
    """Check, before anything is computed, that ``out_dir`` can take a run's files.

    A directory holding files (but the temporaries of interrupted writes) is refused
    unless ``overwrite``; nothing is removed here: the new run replaces the earlier run's
    files (:data:`RUN_FILES`) only once it is complete.

    Raises
    ------
    ConfigError
        ``--out`` is a file or lies under one, is not writable, or holds files without ``--overwrite``.
    """
    try:
        blocking = next((p for p in (out_dir, *out_dir.parents) if p.exists() and not p.is_dir()), None)
        present = sorted(p.name for p in out_dir.iterdir() if not is_temporary(p)) if out_dir.is_dir() and blocking is None else []
        writable = next(p for p in (out_dir, *out_dir.parents, Path.cwd()) if p.exists())
    except (OSError, ValueError) as exc:  # a name too long, a NUL byte, no permission
        raise ConfigError(f"--out: expected a usable directory path, received {short_repr(str(out_dir))} "
                          f"({getattr(exc, 'strerror', None) or exc})") from None
    if blocking is not None:
        raise ConfigError(f"--out: expected a directory, received {out_dir} ({blocking} is a file)")
    if present and not overwrite:
        shown = ", ".join(present[:4]) + (", ..." if len(present) > 4 else "")
        raise ConfigError(f"--out: expected a new or empty directory (or --overwrite), received {out_dir}, which holds {shown}")
    if not os.access(writable, os.W_OK | os.X_OK):
        raise ConfigError(f"--out: expected a writable directory, received {out_dir} ({writable} is not writable)")


@app.command("validate")
def validate_command(scenario: Annotated[str, typer.Argument(help="A scenario or sweep: a YAML file or a shipped name.")],
                     memory_budget: MemoryBudgetOption = None, assignments: SetOption = None) -> None:
    """Check a scenario (or a sweep, every grid point of it) without running it: everything a run would read."""
    use_memory_budget(memory_budget)
    if is_sweep(scenario):
        if assignments:
            raise ConfigError(f"--set: expected a scenario, received the sweep {scenario} (a sweep sets fields under overrides: and grid:)")
        from ..experiments import plan_sweep

        plan = plan_sweep(scenario)
        typer.echo(f"ok: {plan.source or scenario} (sweep: {len(plan.combinations)} grid points × {len(plan.seeds)} seeds = {len(plan.tasks)} runs)")
        return
    spec = scenario_with(scenario, assignments)
    settings = "".join(f" --set {text}" for text in assignments or ())
    typer.echo(f"ok: {spec.source or scenario}{settings} ({spec.family})")


def scenario_with(scenario: str, assignments: list[str] | None):
    """The validated scenario with the ``--set`` arguments applied (:mod:`robofleet.cli.overrides`)."""
    from .overrides import load_with_assignments

    return load_with_assignments(scenario, assignments)


def is_sweep(ref: str) -> bool:
    """Whether ``ref`` names a sweep: a YAML file with a top-level ``scenario`` key and no
    ``family`` key, or a shipped sweep name that is no scenario name."""
    from ..core.config import read_mapping

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
def check_command(scenario: ScenarioArgument, assignments: SetOption = None) -> None:
    """Report which of its paper's checkable conditions a scenario meets, and what follows."""
    spec = scenario_with(scenario, assignments)
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
    names: Annotated[Optional[list[str]], typer.Argument(
        metavar="NAME", help="Show these scenarios (or, with --sweeps, sweeps) with their full descriptions.", show_default=False)] = None,
    family: Annotated[Optional[str], typer.Option(help="Only this family's scenarios.")] = None,
    sweeps: Annotated[bool, typer.Option("--sweeps", help="List the shipped sweeps instead.")] = False,
    long: Annotated[bool, typer.Option("--long", help="Full descriptions (the file's whole leading comment), not their first sentence.")] = False,
) -> None:
    """List the shipped scenarios (name, family, description); every command takes these names.

    With NAME (or --long): full descriptions, one paragraph each."""
    if family is not None and family not in FAMILIES:
        raise RobofleetError(f"--family: expected one of {sorted(FAMILIES)}, received {family!r}")
    kind = "sweeps" if sweeps else "scenarios"
    if names:
        root = catalogue.folder(kind)
        entries = [catalogue.describe(catalogue.path(name, kind), root, kind) for name in names]
    else:
        entries = catalogue.list(kind)
    entries = [e for e in entries if family is None or e.family == family]
    if names or long:
        typer.echo("\n\n".join(long_description(entry) for entry in entries))
        return
    width = max((len(e.name) for e in entries), default=0)
    for entry in entries:
        typer.echo(f"{entry.name:<{width}}  {entry.family:<12}  {entry.description}")


def long_description(entry: catalogue.Entry, width: int = 88) -> str:
    """A catalogue entry with its full description: ``name (family)``, then the file's
    whole leading comment, wrapped and indented, then the file."""
    import textwrap

    text = catalogue.leading_comment(entry.path.read_text()) or "(no description)"
    body = textwrap.fill(text, width=width, initial_indent="    ", subsequent_indent="    ", break_on_hyphens=False)
    return f"{entry.name} ({entry.family})\n{body}\n    file: {entry.path}"


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
    from ..experiments import run_sweep

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
    from rich.console import Console

    from ..experiments import summarize_sweep
    from .display import COLUMN_WIDTH, MIN_TABLE_COLUMNS, PREFERRED_COLUMNS, frame_table

    means = summarize_sweep(frame)
    leading = list(means.columns[: len(frame.attrs["grid"]) + 2])
    values = [c for c in means.columns if c not in leading]
    values = [c for c in PREFERRED_COLUMNS if c in values] + [c for c in values if c not in PREFERRED_COLUMNS]
    console = Console()
    fits = max(MIN_TABLE_COLUMNS, console.width // COLUMN_WIDTH - len(leading))
    console.print(frame_table(means[leading + values], "means per parameter combination", leading=len(leading), values=fits))


REPRODUCE_SUMMARY = "Reproduce a paper's experiment: sweeps, summary.csv, table.md and figures."


class ReproduceCommand(TyperCommand):
    """``reproduce``, whose help lists the declared reproductions and their papers: the
    declarations (and the libraries their tables and figures use) are imported only when
    that help is shown."""

    def format_help_text(self, ctx, formatter) -> None:
        from ..experiments.reproductions import REPRODUCTIONS

        self.help = f"{REPRODUCE_SUMMARY} NAME is one of: " + "; ".join(f"{r.name} ({r.paper})" for r in REPRODUCTIONS.values())
        super().format_help_text(ctx, formatter)


@app.command("reproduce", cls=ReproduceCommand, help=REPRODUCE_SUMMARY)
def reproduce_command(
    name: Annotated[str, typer.Argument(help="The experiment: one of the names above.")],
    out: OutOption = None,
    seeds: Annotated[Optional[int], typer.Option(min=1, help="Seeds per grid point (overrides the budget's).")] = None,
    budget: Annotated[str, typer.Option(help="How much to run: smallest (a smoke run), default, or full (the paper's size).")] = "default",
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    quiet: QuietOption = False,
) -> None:
    from ..experiments import reproduce as run_reproduction
    from ..experiments.reproductions import REPRODUCTIONS

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
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace --out / --rerun files that robofleet did not write.")] = False,
) -> None:
    """Write a self-contained HTML replay of a run (or one report of a reproduction) and open it.

    Writes only FILE.html (and FILE.rrd), so never a run's or a reproduction's own data; an
    existing file is replaced only if robofleet wrote it (a page or a recording), or with
    --overwrite; each file is replaced only once complete.
    """
    from ..core.trace import Trace
    from ..viz.replay.page import open_in_browser, write_html
    from ..viz.replay.report import write_report
    from ..viz.replay.target import locate

    target = locate(run)
    page = out if out is not None else target.default_output()
    check_view_outputs(page, rerun, target, overwrite)
    outputs = [page] if rerun is None else [page, rerun]
    before = {path: file_identity(path) for path in outputs}
    try:
        if target.kind == "reproduction":
            write_report(target.directory, page)
        else:
            scene = replay_scene_of(Trace.load(target.directory), target.directory, max_frames)
            write_html(scene, page)
            if rerun is not None:
                from ..viz.replay.rerun_export import write_rrd

                write_rrd(scene, rerun)
    except KeyboardInterrupt:
        written = [str(path) for path in outputs if file_identity(path) != before[path]]
        raise Stopped(f"interrupted; {'wrote ' + ', '.join(written) + ' only' if written else 'nothing was written'}") from None
    typer.echo("wrote " + ", ".join(str(p) for p in outputs))
    if not no_open and not open_in_browser(page):
        typer.echo(f"no browser to open here; open {page.resolve().as_uri()}")


PAGE_SUFFIXES = (".html", ".htm")


def check_view_outputs(page: Path, rerun: Path | None, target, overwrite: bool) -> None:
    """Refuse, before anything is written, outputs that could lose data: ``--out`` and
    ``--rerun`` naming one file, a page that is no ``.html`` file (so never a run's trace or
    summary, nor a reproduction's tables), a recording that is no ``.rrd`` file or of no run,
    and an existing file robofleet did not write, unless ``overwrite``."""
    from ..viz.replay.page import is_robofleet_page
    from ..viz.replay.rerun_export import is_robofleet_recording

    if rerun is not None and same_file(page, rerun):
        raise ConfigError(f"--rerun: expected a file other than the page, received {rerun}, which is also the page (--out {page})")
    if page.suffix.lower() not in PAGE_SUFFIXES:
        raise ConfigError(f"--out: expected a FILE.html, received {page}")
    if rerun is not None and (target.kind != "run" or rerun.suffix != ".rrd"):
        raise ConfigError(f"--rerun: expected a FILE.rrd for a run directory, received {rerun} for {target.kind} {target.directory}")
    for option, path, ours in (("--out", page, is_robofleet_page), ("--rerun", rerun, is_robofleet_recording)):
        if path is not None and not overwrite and (path.exists() or path.is_symlink()) and not ours(path):
            raise ConfigError(f"{option}: expected a new file or one robofleet wrote (or --overwrite), received {path}, "
                              "which is another file")


def file_identity(path: Path) -> tuple[int, int] | None:
    """What tells a file replaced since (its inode and modification time), or ``None`` if absent."""
    try:
        status = path.stat()
    except OSError:
        return None
    return status.st_ino, status.st_mtime_ns


def same_file(a: Path, b: Path) -> bool:
    """Whether two paths name the same file (after resolving links and ``..``)."""
    try:
        return a.resolve() == b.resolve()
    except (OSError, RuntimeError):
        return a.absolute() == b.absolute()


def replay_scene_of(trace, directory: Path, max_frames: int):
    """The replay scene of a loaded trace, built by its family's replay module."""
    from ..viz.replay import scene_builder

    if trace.family not in FAMILIES:
        raise ConfigError(f"{directory / 'trace.json'}: family: expected one of {sorted(FAMILIES)}, received {trace.family!r}")
    try:
        return scene_builder(trace.family)(trace, max_frames=max_frames)
    except RobofleetError:
        raise
    except KeyError as exc:
        raise ConfigError(f"{directory}: expected a complete {trace.family} trace, received one without {exc}") from None
    except (TypeError, ValueError, IndexError, AttributeError, ArithmeticError) as exc:
        # values of the right kinds that do not fit together (a trace edited by hand, or written before its schema was recorded)
        raise ConfigError(f"{directory}: expected trace fields that fit together, received a {trace.family} trace its replay "
                          f"cannot draw ({type(exc).__name__}: {one_line(exc)})") from None


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


@functools.cache
def click_command(commands: int, groups: int) -> TyperGroup:
    """The click command typer builds from :data:`app` and its ``commands`` and ``groups``,
    built once per process (building reads every command's signature and annotations,
    tens of milliseconds, which a program calling :func:`main` again need not pay)."""
    return typer.main.get_command(app)


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning robofleet errors into one line and exit status 2.
    Unexpected exceptions propagate with Python's own traceback."""
    warnings.showwarning = show_warning
    budget = os.environ.get(MEMORY_BUDGET_VARIABLE)
    try:
        code = click_command(len(app.registered_commands), len(app.registered_groups))(args=argv, standalone_mode=False)
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
    if code == INTERRUPTED:  # typer's answer to Ctrl-C in a command that does not say more
        typer.echo("interrupted; every file written so far is complete (none is left half-written)", err=True)
    if isinstance(code, int) and code:
        sys.exit(code)


if __name__ == "__main__":
    main()
