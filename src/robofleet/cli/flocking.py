"""CLI of the ``flocking`` family (paper 001).

* ``robofleet reproduce flocking [--seeds N] [--out DIR] [--executor ...] [--scheduler ADDR]``:
  the Fig. 11 curves, the traces of Figs. 9-10, the variant comparison, ``table.md``
  and two animations.
* ``robofleet flocking-check SCENARIO``: the pattern checks and conditions (1)-(3) of
  Sec. 3.2 for a scenario (a priori, from its speeds and scheduler bounds).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from .common import ExecutorOption, SchedulerOption, WorkersOption, load_family


def register(app: typer.Typer, reproduce: typer.Typer) -> None:
    """Add ``reproduce flocking`` and ``flocking-check``."""
    reproduce.command("flocking")(reproduce_flocking_command)
    app.command("flocking-check")(flocking_check_command)


def reproduce_flocking_command(
    seeds: Annotated[int, typer.Option(min=1, help="Seeds per pattern (Fig. 11) and per comparison cell.")] = 10,
    compare_seeds: Annotated[Optional[int], typer.Option(min=1, help="Seeds per comparison cell (default: --seeds).")] = None,
    duration: Annotated[float, typer.Option(min=10, help="Simulated time per run (leader moves).")] = 1500.0,
    out: Annotated[Path, typer.Option(help="Output directory.")] = Path("results/flocking"),
    executor: ExecutorOption = "process",
    scheduler: SchedulerOption = None,
    workers: WorkersOption = None,
    animate: Annotated[bool, typer.Option(help="Write the wedge and spread animations.")] = True,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress bars.")] = False,
) -> None:
    """Reproduce Figs. 9-11 of paper 001 and compare basic, stripe, hula-hoop and randomized."""
    from ..flocking.reproduce import reproduce_flocking, run_one
    from ..viz import flocking as viz

    result = reproduce_flocking(out, seeds, duration=duration, compare_seeds=compare_seeds, executor=executor,
                                scheduler=scheduler, workers=workers, progress=not quiet)
    written = [viz.plot_delta_curves(result["curves"], out / "fig11_delta.png"),
               viz.plot_comparison(result["comparison_table"], out / "comparison.png")]
    for name, pattern in (("fig9_wedge", "wedge"), ("fig10_spread", "spread")):
        trace = run_one({"pattern": pattern, "duration": duration, "seed": 9})
        trace.save(out / f"{name}_trace")
        written.append(viz.plot_trace(trace, out / f"{name}.png"))
        if animate:
            written.append(viz.animate_trace(trace, out / f"{name}.gif"))
    typer.echo(Path(result["table"]).read_text())
    typer.echo(f"wrote {out}/ {{table.md, fig11_runs/, comparison_runs/, " + ", ".join(p.name for p in written) + "}")


def flocking_check_command(scenario: Annotated[Path, typer.Argument(help="Scenario YAML file of family flocking.")]) -> None:
    """Report the pattern checks and conditions (1)-(3) of Sec. 3.2 for a scenario."""
    import numpy as np

    from ..core.rng import keyed_generator
    from ..flocking.leader import check_conditions, resolve_speeds
    from ..flocking.patterns import make_pattern

    spec = load_family(scenario, "flocking")
    p = spec.pattern
    pattern = make_pattern(p.kind, points=p.points, n_points=p.n_points, path=p.path, rng=keyed_generator(0, "pattern"), source=spec.source)
    typer.echo(f"pattern {pattern.name}: {pattern.size} slots, R_P = {pattern.radius:.4g}, lb-symmetric: {pattern.is_lb_symmetric}, "
               f"points on the axis: {pattern.n_on_axis}")
    f = spec.followers
    speeds = np.asarray(f.speeds, float) if f.speeds else np.array([f.speed_min])
    v, w = resolve_speeds(spec.leader, speeds, pattern.radius)
    tau = spec.scheduler.move_time_max
    xi = 2.0 * pattern.size * (v + w * pattern.radius) * tau if spec.xi == "auto" else float(spec.xi)
    report = check_conditions(v, w, pattern.radius, np.full(pattern.size, speeds.min()), tau, xi, on_violation="ignore")
    for name, ok in report.holds.items():
        if name != "condition_4":
            typer.echo(f"{'holds' if ok else 'FAILS'}  {name}")
    for line in report.violations():
        typer.echo(f"  {line}")
    typer.echo(f"v_L = {v:.4g}, ω_L = {w:.4g}, slowest follower ≥ {speeds.min():.4g}, ξ = {xi:.4g}; "
               "condition (4) is measured on the cycle log of each run (results: condition_4).")
