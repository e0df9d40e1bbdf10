"""The ``robofleet ros2 …`` commands and ``robofleet export``, registered by the main CLI.

Each command checks the ``ros2`` extra first (a one-line error naming it), then builds
its node from the library (:mod:`.sim`, :mod:`.filter`, :mod:`.supervisor`,
:mod:`.launch`, :mod:`.mcap_export`) and spins it until it is done or stopped (Ctrl-C:
a clean stop, exit status 0).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Optional

import typer
import yaml

from ..core.errors import ConfigError, short_repr
from . import require_ros
from .runtime import DEFAULT_PREFIX

ros2_app = typer.Typer(no_args_is_help=True, rich_markup_mode=None,
                       help="ROS 2 nodes: a simulated fleet, the B-UAVC safety filter, the RMTRACK supervisor, and a launcher (ros2 extra).")

SetOption = Annotated[Optional[list[str]], typer.Option("--set", help="Override a scenario field, e.g. --set robots.sigma=0 (repeatable).")]
PrefixOption = Annotated[str, typer.Option(help="Robot namespaces are /<prefix>0, /<prefix>1, …")]
SimTimeOption = Annotated[bool, typer.Option("--use-sim-time", help="Follow /clock (as published by `robofleet ros2 sim`).")]
SeedOption = Annotated[int, typer.Option(min=0, help="Seed of the scenario's layout (and of the simulated noise and faults).")]


def overrides_of(items: list[str] | None) -> dict[str, Any] | None:
    """``["robots.sigma=0", …]`` as ``{"robots.sigma": 0, …}`` (values read as YAML)."""
    if not items:
        return None
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"--set: expected FIELD=VALUE such as robots.sigma=0, received {short_repr(item)}")
        try:
            out[key] = yaml.safe_load(value)
        except yaml.YAMLError:
            raise ConfigError(f"--set: expected a YAML value after '=', received {short_repr(value)}") from None
    return out


@ros2_app.command("sim")
def sim_command(
    scenario: Annotated[str, typer.Argument(help="A 2-D avoidance scenario (or a coordination scenario: plan followers).")],
    set_: SetOption = None,
    nominal: Annotated[str, typer.Option(help="none, or go-to-goal: also publish a straight-to-goal <ns>/cmd_vel_nav.")] = "none",
    seed: SeedOption = 0,
    prefix: PrefixOption = DEFAULT_PREFIX,
    speed: Annotated[float, typer.Option(help="Simulated seconds per wall second (others then need --use-sim-time).")] = 1.0,
    cmd_timeout: Annotated[float, typer.Option(help="A robot holds when its last cmd_vel is older than this [simulated s].")] = 0.5,
    out: Annotated[Optional[Path], typer.Option(help="Write the run here when it ends (a new or empty directory).")] = None,
    wait_for_cmd_vel: Annotated[bool, typer.Option("--wait-for-cmd-vel", help="Start moving once every robot's cmd_vel (coordination: until) has a publisher.")] = False,
    lockstep: Annotated[bool, typer.Option("--lockstep", help="Each step waits (up to --cmd-timeout) for every robot's cmd_vel answering its poses.")] = False,
    drop: Annotated[float, typer.Option(help="Coordination: probability that a report or an until message is lost.")] = 0.0,
    delay: Annotated[float, typer.Option(help="Coordination: messages arrive up to this late [simulated s].")] = 0.0,
) -> None:
    """Simulate a fleet: <ns>/pose out, <ns>/cmd_vel in (avoidance), or <ns>/progress out, <ns>/until in (coordination)."""
    require_ros("robofleet ros2 sim")
    from ..scenarios import load_scenario
    from .runtime import checked_prefix, run_node
    from .sim import SimOptions, make_sim_node

    spec = load_scenario(scenario, overrides_of(set_))
    options = SimOptions(seed=seed, nominal=nominal, prefix=checked_prefix(prefix), speed=speed, cmd_timeout=cmd_timeout, out=out,
                         wait_for_cmd_vel=wait_for_cmd_vel, lockstep=lockstep, drop=drop, delay=delay).checked()
    raise typer.Exit(run_node(lambda: make_sim_node(spec, options), done=lambda node: node.done))


@ros2_app.command("filter")
def filter_command(
    scenario: Annotated[str, typer.Argument(help="A 2-D single-integrator avoidance scenario, or a ros__parameters YAML file.")],
    set_: SetOption = None,
    robot: Annotated[Optional[int], typer.Option(help="Filter this robot only (one node per robot); default: the whole fleet.")] = None,
    prefix: Annotated[Optional[str], typer.Option(help="Robot namespaces are /<prefix>0, … (default: robot, or the parameter file's).")] = None,
    frame: Annotated[Optional[str], typer.Option(help="Frame of cmd_vel_nav and cmd_vel: map (default) or base (the robot's, rotated by its yaw).")] = None,
    pose_timeout: Annotated[Optional[float], typer.Option(help="A robot whose own pose is older gets zero velocity [s] (default 5 dt).")] = None,
    no_deadlock_memory: Annotated[bool, typer.Option("--no-deadlock-memory", help="Turn off the deadlock recovery (appendix C).")] = False,
    use_sim_time: SimTimeOption = False,
) -> None:
    """The B-UAVC safety filter: <ns>/cmd_vel_nav in, <ns>/cmd_vel out, every <ns>/pose read."""
    require_ros("robofleet ros2 filter")
    from .filter import make_filter_node, settings_from
    from .runtime import run_node

    settings = settings_from(scenario, overrides_of(set_), prefix=prefix, velocity_frame=frame, pose_timeout=pose_timeout,
                             deadlock_memory=not no_deadlock_memory)
    raise typer.Exit(run_node(lambda: make_filter_node(settings, robot, use_sim_time)))


@ros2_app.command("supervisor")
def supervisor_command(
    scenario: Annotated[str, typer.Argument(help="A coordination scenario.")],
    set_: SetOption = None,
    seed: SeedOption = 0,
    prefix: PrefixOption = DEFAULT_PREFIX,
    reports: Annotated[str, typer.Option(help="What the robots report: progress (<ns>/progress) or pose (<ns>/pose).")] = "progress",
    use_sim_time: SimTimeOption = False,
) -> None:
    """The online RMTRACK supervisor: <ns>/progress (or <ns>/pose) in, <ns>/until and <ns>/plan out."""
    require_ros("robofleet ros2 supervisor")
    from ..scenarios import load_scenario
    from .runtime import checked_prefix, run_node
    from .supervisor import make_supervisor_node, supervisor_of

    supervisor = supervisor_of(load_scenario(scenario, overrides_of(set_)), seed)
    node_prefix = checked_prefix(prefix)
    raise typer.Exit(run_node(lambda: make_supervisor_node(supervisor, node_prefix, use_sim_time, reports)))


@ros2_app.command("launch")
def launch_command(
    file: Annotated[Path, typer.Argument(help="A launch file: nodes (sim, filter, supervisor) with their scenario and options.")],
    grace: Annotated[float, typer.Option(help="Seconds the nodes get to stop after Ctrl-C before they are terminated.")] = 10.0,
) -> None:
    """Start the nodes of a launch file; Ctrl-C stops them all cleanly."""
    require_ros("robofleet ros2 launch")
    from .launch import launch

    raise typer.Exit(launch(file, grace))


def export_command(
    run: Annotated[Path, typer.Argument(help="A run directory (trace.npz + trace.json), e.g. from `robofleet run` or `robofleet ros2 sim --out`.")],
    mcap: Annotated[Path, typer.Option("--mcap", help="Write the run as ROS 2 messages to FILE.mcap (Foxglove, ros2 bag).")],
    prefix: PrefixOption = DEFAULT_PREFIX,
) -> None:
    """Export a run: poses with covariance, goals and cells as ROS 2 messages (MCAP)."""
    require_ros("robofleet export --mcap")
    from .mcap_export import export_mcap
    from .runtime import checked_prefix

    path, count = export_mcap(run, mcap, checked_prefix(prefix))
    typer.echo(f"wrote {path} ({count} messages)")
