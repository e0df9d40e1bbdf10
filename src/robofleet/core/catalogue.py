"""The shipped catalogue: scenario and sweep files addressable by name.

Every shipped scenario has a name, its path below the catalogue folder without
``.yaml`` (``avoidance/circle_swap``); every shipped sweep likewise (``buavc_noise``).
A checkout's own ``scenarios/`` and ``sweeps/`` folders win (so edits are picked up);
an installed wheel carries copies as ``robofleet/_scenarios`` and ``robofleet/_sweeps``.

Every command, :func:`robofleet.load_scenario` and every object built from a scenario
(:func:`~robofleet.core.config.load_spec`) accept a name wherever they accept a path;
:func:`resolve` decides which one was meant (an existing file wins). The catalogue knows
files, not families, so it sits in the core layer where every package can use it.
"""

from __future__ import annotations

import builtins
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import yaml

from ..core.errors import ConfigError, ScenarioError, short_repr

SUFFIX = ".yaml"
YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml when built with it: `robofleet scenarios` reads every file
ALIASES = {  # names of the files' earlier home, kept working
    "avoidance_models/diff_drive": "avoidance/diff_drive",
    "avoidance_models/double_integrator": "avoidance/double_integrator",
    "avoidance_models/heterogeneous": "avoidance/heterogeneous",
    "avoidance_models/quadrotors_3d": "avoidance/quadrotors_3d",
}


@dataclass(frozen=True)
class Entry:
    """One shipped file: its ``name``, ``family`` (``"sweep"`` for sweeps), the first
    sentence of its leading comment as ``description``, and its ``path``."""

    name: str
    family: str
    description: str
    path: Path


KINDS = ("scenarios", "sweeps")


def folder(kind: str) -> Path:
    """The folder of shipped ``kind`` files (``"scenarios"`` or ``"sweeps"``)."""
    if kind not in KINDS:
        raise ConfigError(f"kind: expected one of {builtins.list(KINDS)}, received {kind!r}")
    checkout = Path(__file__).resolve().parents[3] / kind
    if checkout.is_dir() and (checkout.parent / "pyproject.toml").exists():
        return checkout
    return Path(str(resources.files("robofleet") / f"_{kind}"))


def list(kind: str = "scenarios") -> builtins.list[Entry]:  # noqa: A001 - the documented name
    """Every shipped scenario (or, with ``kind="sweeps"``, sweep), sorted by name.

    A scenario file is one with a top-level ``family:`` key (other YAML files below the
    folder, such as flocking pattern files, are data a scenario refers to).
    """
    root = folder(kind)
    entries = [describe(path, root, kind) for path in sorted(root.rglob(f"*{SUFFIX}"))]
    return sorted((e for e in entries if e.family), key=lambda e: e.name)


def names(kind: str = "scenarios") -> builtins.list[str]:
    """The names of :func:`list`."""
    return [e.name for e in list(kind)]


def path(name: str, kind: str = "scenarios") -> Path:
    """The file of the shipped scenario (or sweep) ``name``.

    ``name`` may carry the folder and suffix of a checkout path
    (``scenarios/avoidance/circle_swap.yaml``), so such paths work from any directory.

    Raises
    ------
    ScenarioError
        If there is no such shipped file; the message lists a few close names.
    """
    key = str(name).removesuffix(SUFFIX).strip("/").removeprefix(f"{kind}/")
    key = ALIASES.get(key, key)
    candidate = folder(kind) / f"{key}{SUFFIX}"
    if key and is_file(candidate):
        return candidate
    known = names(kind)
    close = [n for n in known if key.split("/")[-1] in n] or known
    hint = ", ".join(close[:6]) + (", ..." if len(close) > 6 else "")
    raise ScenarioError("", f"a file or a shipped {kind[:-1]} name ({hint}; `robofleet {kind}` lists them all)", str(name),
                        source=short_repr(str(name), 60).strip("'"))


def resolve(ref: str | Path, kind: str = "scenarios", base: Path | None = None) -> Path:
    """A path for ``ref``: an existing file (relative to ``base`` if given), else the
    shipped file of that name."""
    given = Path(ref)
    for candidate in ((base / given,) if base is not None and not given.is_absolute() else ()) + (given,):
        if is_file(candidate):
            return candidate
    if is_file(given, exists=True):
        raise ScenarioError("", f"a {kind[:-1]} file", f"a directory ({given})", source=str(given))
    try:
        return path(str(ref), kind)
    except ScenarioError:
        if given.suffix in (".yaml", ".yml") or given.is_absolute():
            return given  # meant as a file: reading it reports it missing or unreadable
        raise


def is_file(path: Path, exists: bool = False) -> bool:
    """``path.is_file()`` (``path.exists()`` with ``exists``), ``False`` for a name the
    system cannot even look up (too long, a NUL byte)."""
    try:
        return path.exists() if exists else path.is_file()
    except (OSError, ValueError):
        return False


def describe(file: Path, root: Path, kind: str) -> Entry:
    """The catalogue entry of one shipped file."""
    name = file.relative_to(root).with_suffix("").as_posix()
    text = file.read_text()
    description = first_sentence(leading_comment(text))
    if kind == "sweeps":
        family = "sweep"
    else:
        data = yaml.load(text, Loader=YAML_LOADER)
        family = str(data["family"]) if isinstance(data, dict) and "family" in data else ""
    return Entry(name, family, description, file)


def leading_comment(text: str) -> str:
    """The comment block at the top of a YAML file, as one line."""
    lines = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        lines.append(line[1:].strip())
    return " ".join(part for part in lines if part)


ABBREVIATIONS = ("Fig", "Figs", "Sec", "Eq", "e.g", "i.e", "vs", "cf", "al")
DESCRIPTION_LENGTH = 110


def first_sentence(text: str, limit: int = DESCRIPTION_LENGTH) -> str:
    """``text`` up to the end of its first sentence (a period and a space, not after an
    abbreviation such as "Fig."), cut to ``limit`` characters."""
    words, out = text.split(" "), []
    for word in words:
        out.append(word)
        if word.endswith(".") and word.lstrip("(").rstrip(".") not in ABBREVIATIONS:
            break
    sentence = " ".join(out)
    return sentence if len(sentence) <= limit else sentence[: limit - 1].rstrip() + "…"
