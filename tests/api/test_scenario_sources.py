"""One way to build every object embedded from a scenario: a shipped name, a file (a string
or a path), a mapping or a validated spec are accepted alike by the safety filter, the
PettingZoo environment, the supervisor and ``load_scenario``; anything else is one line
naming what was received."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from robofleet import load_scenario
from robofleet.avoidance import RobotSafetyFilter, SafetyFilter
from robofleet.coordination import Supervisor
from robofleet.core.errors import ConfigError, RobofleetError
from robofleet.scenarios import catalogue


def env_of(source):
    pytest.importorskip("pettingzoo")
    from robofleet.envs import parallel_env

    return parallel_env(source, max_steps=5)


AVOIDANCE, COORDINATION = "avoidance/three_boxes", "coordination/x_corridor_5_tff"
BUILDERS = {  # object -> (the scenario it embeds, how to build it from a source, what is compared)
    "SafetyFilter": (AVOIDANCE, SafetyFilter.from_spec,
                     lambda f: (f.n, f.dt, f.v_max.tolist(), f.model.radius.tolist(), f.obstacle_count, f.model.local_box)),
    "RobotSafetyFilter": (AVOIDANCE, lambda s: RobotSafetyFilter.from_spec(s, robot=1),
                          lambda f: (f.radius, f.v_max, f.dt, f.quantile, f.local_box)),
    "parallel_env": (AVOIDANCE, env_of, lambda e: (e.possible_agents, e.spec.model_dump_json(), e.v_max.tolist())),
    "Supervisor": (COORDINATION, Supervisor.from_scenario,
                   lambda s: (s.traj.n_robots, [p.tolist() for p in s.traj.positions], s.space.n_obstacles)),
}
ARGUMENT = {"SafetyFilter": "spec", "RobotSafetyFilter": "spec", "parallel_env": "scenario", "Supervisor": "spec"}


def sources(name: str, tmp_path: Path) -> dict:
    """The scenario ``name`` as every kind of source, the file both as a string and as a
    path, inside and outside the catalogue folder."""
    shipped = catalogue.path(name)
    copy = tmp_path / "elsewhere" / shipped.name
    copy.parent.mkdir()
    shutil.copy(shipped, copy)
    return {"name": name, "file (str)": str(shipped), "file (Path)": shipped, "file copy": copy,
            "mapping": yaml.safe_load(shipped.read_text()), "spec": load_scenario(name)}


@pytest.mark.parametrize("built", sorted(BUILDERS))
def test_every_kind_of_source_builds_the_same_object(built, tmp_path):
    name, build, signature = BUILDERS[built]
    expected = None
    for kind, source in sources(name, tmp_path).items():
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = signature(build(source))
        expected = got if expected is None else expected
        assert got == expected, f"{built} from a {kind} differs"


def test_load_scenario_takes_the_same_sources(tmp_path):
    specs = [load_scenario(source) for source in sources(COORDINATION, tmp_path).values()]
    assert all(s.model_dump() == specs[0].model_dump() for s in specs)
    spec = load_scenario(AVOIDANCE)
    assert load_scenario(spec) is spec


def bad_sources(tmp_path: Path, wanted: str) -> dict:
    """Sources that are no scenario of the family ``wanted``: ``(source, text the message must show)``."""
    other = COORDINATION if wanted == "avoidance" else AVOIDANCE
    no_family = yaml.safe_load(catalogue.path(COORDINATION).read_text())
    no_family.pop("family")
    return {
        "a number": (5, "int 5"), "None": (None, "None"), "an empty string": ("", "''"), "blanks": ("   ", "'   '"),
        "a list": ([1, 2], "[1, 2]"), "bytes": (b"avoidance/three_boxes", "b'avoidance/three_boxes'"),
        "an unknown name": ("avoidance/nope", "'avoidance/nope'"),
        "a missing file": (tmp_path / "missing.yaml", "No such file"),
        "a directory": (tmp_path, "a directory ("),
        "a file that is not YAML": (write(tmp_path / "bad.yaml", "a: [1,\n"), "bad.yaml"),
        "a file that is not a mapping": (write(tmp_path / "list.yaml", "- 1\n"), "list"),
        "another family's name": (other, "of family"),
        "another family's file": (catalogue.path("search/fig7"), "of family 'search'"),
        "another family's mapping": ({"family": "flocking"}, "a mapping of family 'flocking'"),
        "another family's spec": (load_scenario(other), "scenario spec"),
        "an unknown family": ({"family": "nope"}, "'nope'"),
        "a part of a spec": (load_scenario(AVOIDANCE).robots, "RobotsSpec (not a whole scenario)"),
        "an invalid field": ({"family": wanted, "name": 3}, "name"),
        **({"a mapping without family:": (no_family, "without a family: key")} if wanted == "coordination" else {}),
    }


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("built", sorted(BUILDERS))
def test_bad_sources_are_one_line_errors_naming_what_was_received(built, tmp_path):
    name, build, _ = BUILDERS[built]
    wanted = name.split("/")[0]
    for kind, (source, shown) in bad_sources(tmp_path, wanted).items():
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(RobofleetError) as info:
                build(source)
        message = str(info.value)
        assert isinstance(info.value, (ValueError, TypeError)), (kind, type(info.value).__mro__)
        assert "\n" not in message and "expected" in message and "received" in message, (kind, message)
        assert shown in message, (kind, message)
        if isinstance(info.value, ConfigError):  # an argument error names the argument
            assert message.startswith(f"{ARGUMENT[built]}: "), (kind, message)


def test_a_spec_with_overrides_is_refused_in_one_line():
    spec = load_scenario(AVOIDANCE)
    with pytest.raises(ConfigError, match=r"^overrides: expected None for a validated spec .*received \{'robots.n': 3\}$"):
        load_scenario(spec, {"robots.n": 3})
    pytest.importorskip("pettingzoo")
    from robofleet.envs import parallel_env

    with pytest.raises(ConfigError, match=r"^overrides: expected None for a validated spec"):
        parallel_env(spec, overrides={"robots.n": 3})
    assert np.array_equal(parallel_env(AVOIDANCE, overrides={"robots.n": 3}).v_max, np.full(3, spec.robots.v_max))
