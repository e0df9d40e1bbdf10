"""No dangling references: every repository path, docs page, docs section, Python name,
shipped scenario, sweep, reproduction and benchmark option cited in the docstrings, the
scenario and sweep files, the examples, the README and the docs exists.

Templates (``docs/results/<family>.md``) are not references; a glob (``scenarios/*.yaml``)
must match at least one file.
"""

from __future__ import annotations

import importlib
import re
from functools import lru_cache
from pathlib import Path

import pytest

from markdown_blocks import ROOT

DOCS = ROOT / "docs"
SOURCES = (
    [ROOT / "README.md"]
    + sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)
    + sorted((ROOT / "src").rglob("*.py"))
    + sorted((ROOT / "scenarios").rglob("*.yaml"))
    + sorted((ROOT / "sweeps").glob("*.yaml"))
    + sorted(p for p in (ROOT / "examples").rglob("*") if p.suffix in (".py", ".yaml"))
    + sorted((ROOT / "benchmarks").glob("*.py"))
)
TOP = r"(?:src|docs|scenarios|sweeps|examples|benchmarks|tests|notes)"
REPO_PATH = re.compile(rf"(?<![\w/.~-]){TOP}/[\w./*<>+-]*[\w*>/]")
PACKAGE_FILE = re.compile(r"(?<![\w/.~-])(?:robofleet/)?(?:core|avoidance|coordination|flocking|search|experiments|viz|scenarios|testing|envs|cli|dynamics)/[\w/]*\w\.py\b")
SECTION_REF = re.compile(r"(docs/[\w/.-]+\.md)`{0,2}\)?,? ((?:\"[^\"\n]+\"(?:, )?)+)")
DOC_SECTION_REF = re.compile(r"\{doc\}`(?:[^`<]*<)?([^`>]+)>?`,? ((?:\"[^\"\n]+\"(?:, )?)+)")
LINK = re.compile(r"!?\[[^\]\n]*\]\(([^)\s]+)\)")
DOTTED = re.compile(r"(?<![\w.])robofleet(?:\.[A-Za-z_]\w*)+")
HISTORY = re.compile(r"\bissue \d+|\bstop \d+\b|\bthis stop\b|previous tree|this tree\b|earlier copy|before this change|"
                     r"(?:before|after) the fix\b", re.I)
GENERATED = ("docs/_build", "docs/api/generated")  # written by the build, not kept in the repository
# every page and docstring states results as they stand (benchmark scripts compare against
# earlier trees by design: `--before OLD/src`)


def relative(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def text_of(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def exists(reference: str) -> bool:
    reference = reference.rstrip("/.")
    if reference.startswith(GENERATED):
        return True
    if "<" in reference or "{" in reference:
        return True  # a template, not a reference
    if "*" in reference:
        return any(ROOT.glob(reference))
    return (ROOT / reference).exists()


@lru_cache(maxsize=None)
def headings(page: Path) -> frozenset[str]:
    found = re.findall(r"^#{1,6} (.+?)\s*$", text_of(page), re.M)
    return frozenset(h.replace("`", "") for h in found)


@lru_cache(maxsize=None)
def resolves(dotted: str) -> bool:
    """Whether ``robofleet.a.b.c`` names a module or an attribute of one."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            if not hasattr(obj, name):
                return False
            obj = getattr(obj, name)
        return True
    return False


def missing_paths(path: Path) -> list[str]:
    text = re.sub(r"\{doc\}`[^`]*`|```\{toctree\}.*?```", "", text_of(path), flags=re.S)  # docs pages by name: the Sphinx build checks them
    out = [ref for ref in REPO_PATH.findall(text) if not exists(ref) and not (ROOT / "src/robofleet" / ref).is_file()]
    for ref in PACKAGE_FILE.findall(text):
        name = ref.removeprefix("robofleet/")
        if "<" not in name and not (ROOT / "src/robofleet" / name).exists() and not (ROOT / name).exists():
            out.append(ref)
    return out


def missing_sections(path: Path) -> list[str]:
    text, out = text_of(path), []
    for page, names in SECTION_REF.findall(text):
        for name in re.findall(r'"([^"]+)"', names):
            if not (ROOT / page).is_file() or name not in headings(ROOT / page):
                out.append(f'{page} "{name}"')
    if path.suffix == ".md" and DOCS in path.parents:
        for doc, names in DOC_SECTION_REF.findall(text):
            page = (DOCS / doc.lstrip("/") if doc.startswith("/") else path.parent / doc).with_suffix(".md")
            for name in re.findall(r'"([^"]+)"', names):
                if not page.is_file() or name not in headings(page):
                    out.append(f'{doc} "{name}"')
    return out


def missing_links(path: Path) -> list[str]:
    out = []
    for target in LINK.findall(text_of(path)):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        if not (path.parent / target.split("#")[0]).exists():
            out.append(target)
    return out


@pytest.mark.parametrize("path", SOURCES, ids=relative)
def test_cited_paths_exist(path: Path):
    assert not missing_paths(path), missing_paths(path)


@pytest.mark.parametrize("path", SOURCES, ids=relative)
def test_cited_sections_exist(path: Path):
    assert not missing_sections(path), missing_sections(path)


@pytest.mark.parametrize("path", [p for p in SOURCES if p.suffix == ".md"], ids=relative)
def test_links_resolve(path: Path):
    assert not missing_links(path), missing_links(path)


@pytest.mark.parametrize("path", [p for p in SOURCES if p.suffix in (".md", ".yaml")], ids=relative)
def test_python_names_exist(path: Path):
    names = sorted({name.rstrip(".") for name in DOTTED.findall(text_of(path))})
    assert [name for name in names if not resolves(name)] == []


@pytest.mark.parametrize("path", [p for p in SOURCES if p.parent.name != "benchmarks"], ids=relative)
def test_no_development_history(path: Path):
    assert HISTORY.findall(text_of(path)) == []


# -- commands cited inline ---------------------------------------------------------------------
def cited_commands(text: str) -> list[str]:
    """Every ``robofleet reproduce|sweep|run|check|validate X`` and ``python benchmarks/…`` cited."""
    pattern = r"(robofleet (?:reproduce|sweep|run|check|validate) [\w/.+-]+|python (?:benchmarks|examples)/[\w/.-]+\.py(?: [^`\n|)]*)?)"
    return re.findall(pattern, text)


def command_problem(command: str) -> str | None:
    from robofleet import scenarios
    from robofleet.experiments.reproductions import REPRODUCTIONS

    words = command.split()
    if words[0] == "python":
        script = ROOT / words[1]
        if not script.is_file():
            return f"{words[1]} does not exist"
        source = text_of(script)
        flags = [w.split("=")[0] for w in words[2:] if w.startswith("--")]
        unknown = [flag for flag in flags if f'"{flag}"' not in source]
        return f"{words[1]} takes no {unknown}" if unknown else None
    verb, target = words[1], words[2]
    if target.isupper() or target.startswith("-"):
        return None  # a placeholder (SCENARIO, SWEEP, NAME) or an option list
    if verb == "reproduce":
        return None if target in REPRODUCTIONS else f"no reproduction {target!r}"
    if target.endswith(".yaml") or target.startswith(("runs/", "results/")) or "." in target.split("/")[-1]:
        return None if not target.startswith(("scenarios/", "sweeps/", "examples/")) or (ROOT / target).exists() else f"{target} does not exist"
    kind = "sweeps" if verb == "sweep" else "scenarios"
    try:
        scenarios.catalogue.path(target, kind) if kind == "sweeps" else scenarios.catalogue.path(target)
    except Exception:
        return f"no shipped {kind[:-1]} {target!r}"
    return None


@pytest.mark.parametrize("path", [p for p in SOURCES if p.suffix in (".md", ".py", ".yaml")], ids=relative)
def test_cited_commands_exist(path: Path):
    problems = [f"`{c}`: {command_problem(c)}" for c in cited_commands(text_of(path)) if command_problem(c)]
    assert problems == []
