"""Reference pages generated from the code at build time, so they cannot drift from it.

* ``<!-- scenario-fields: FAMILY -->`` in a page becomes the reference of every field of
  that family's scenario files: type, default and limits read from the spec classes
  (pydantic models), unit and meaning from the field's own ``description`` or, where the
  code gives none, from ``scenario_fields.yaml`` beside this file.
* ``<!-- summary-keys -->`` becomes the table of the summary keys: the core keys, then each
  family's ``FAMILY.results``.
* ``<!-- reproductions -->`` becomes the table of the declared reproductions.

A field without a meaning, or a meaning for a field that no longer exists, is a build
warning (an error under ``make docs``, which builds with ``-W``); :func:`problems` lists
them for the tests.
"""

from __future__ import annotations

import enum
import re
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import yaml
from pydantic import BaseModel
from pydantic_core import PydanticUndefined

NOTES_FILE = Path(__file__).with_name("scenario_fields.yaml")
FIELDS_MARK = "<!-- scenario-fields: "
KEYS_MARK = "<!-- summary-keys -->"
REPRODUCTIONS_MARK = "<!-- reproductions -->"
SHARED = "shared"


def families() -> dict:
    from robofleet.scenarios import FAMILIES

    return FAMILIES


def notes() -> dict:
    """The meanings written beside this file: ``{family or 'shared': {class: {field: [unit, meaning]}}}``."""
    return yaml.safe_load(NOTES_FILE.read_text(encoding="utf-8"))


# -- walking the spec classes -------------------------------------------------------------------
@dataclass
class Section:
    """One model class of a family's spec tree, with every path it appears at."""

    model: type[BaseModel]
    paths: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        return self.paths[0]

    @property
    def kind(self) -> str | None:
        """The ``kind`` this class stands for where a field takes one of several classes."""
        info = self.model.model_fields.get("kind")
        return None if info is None or typing.get_origin(info.annotation) is not typing.Literal else str(info.default)


def models_in(annotation: Any) -> list[type[BaseModel]]:
    """The model classes an annotation holds (``Optional[M]``, ``list[M]``, ``Union[A, B]``)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in models_in(arg)]


def is_list(annotation: Any) -> bool:
    """Whether the annotation is a list (possibly optional)."""
    if typing.get_origin(annotation) is list:
        return True
    return any(is_list(arg) for arg in typing.get_args(annotation) if arg is not type(None))


def sections(spec: type[BaseModel]) -> list[Section]:
    """Every model class under ``spec``, breadth first, with the paths where it appears."""
    found: dict[type, Section] = {spec: Section(spec, [""])}
    queue = [(spec, "")]
    while queue:
        model, path = queue.pop(0)
        for name, info in model.model_fields.items():
            subs = models_in(info.annotation)
            for sub in subs:
                sub_path = f"{path}{name}" + ("[]" if is_list(info.annotation) else "")
                if len(subs) > 1:  # one of several classes, told apart by their kind
                    sub_path += f"{{{Section(sub).kind}}}"
                if sub not in found:
                    found[sub] = Section(sub, [])
                    queue.append((sub, sub_path + "."))
                if sub_path not in found[sub].paths:
                    found[sub].paths.append(sub_path)
    return list(found.values())


def declaring_class(model: type[BaseModel], name: str) -> type:
    """The class of ``model``'s hierarchy that declares field ``name`` last (its own annotation)."""
    for klass in model.__mro__:
        if name in klass.__dict__.get("__annotations__", {}):
            return klass
    return model


def meaning_of(family: str, model: type[BaseModel], name: str, written: dict) -> tuple[str, str] | None:
    """``(unit, meaning)`` of a field: its written note (family, then shared), else the code's description."""
    owner = declaring_class(model, name)
    for scope in (family, SHARED):
        for klass in (model, owner):
            entry = (written.get(scope) or {}).get(klass.__name__, {}).get(name)
            if entry is not None:
                return str(entry[0]), str(entry[1])
    description = model.model_fields[name].description
    return ("", description) if description else None


# -- formatting -------------------------------------------------------------------------------
def type_text(annotation: Any, links: dict[type, str]) -> str:
    """A reader's name for an annotation (``number``, ``one of `a`, `b```, ``list of [x, y]``)."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if annotation is type(None):
        return "null"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return f"mapping, {links[annotation]}"
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        return "one of " + ", ".join(f"`{m.value}`" for m in annotation)
    if origin is typing.Literal:
        return f"`{args[0]}`" if len(args) == 1 else "one of " + ", ".join(f"`{a}`" for a in args)
    if origin in (typing.Union, types.UnionType):
        parts = [a for a in args if a is not type(None)]
        text = " or ".join(type_text(a, links) for a in parts)
        if len(parts) > 1 and all(isinstance(a, type) and issubclass(a, BaseModel) for a in parts):
            text = "mapping, by `kind`: " + ", ".join(links[a] for a in parts)
        return text + (" or null" if len(parts) < len(args) else "")
    if origin is tuple:
        if args and all(a is float for a in args):
            return "[x, y]" if len(args) == 2 else "[x, y, z]" if len(args) == 3 else f"{len(args)} numbers"
        return "list"
    if origin is list:
        if not args:
            return "list"
        inner = args[0]
        if typing.get_origin(inner) is list and typing.get_args(inner) == (float,):
            return "list of points"
        return "list of " + type_text(inner, links)
    return {int: "integer", float: "number", bool: "true or false", str: "text", list: "list", typing.Any: "any"}.get(annotation, str(annotation))


def value_text(value: Any) -> str:
    """A default as it would be written in YAML."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, enum.Enum):
        return str(value.value)
    if value == "":
        return '""'

    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(value_text(v) for v in value) + "]"
    return str(value)


def default_text(info: Any) -> str:
    if info.default_factory is not None:
        made = info.default_factory()
        return "see below" if isinstance(made, BaseModel) else f"`{value_text(made)}`"
    if info.default is PydanticUndefined:
        return "**required**"
    if isinstance(info.default, BaseModel):
        return "see below"
    return f"`{value_text(info.default)}`"


LIMIT_SIGNS = (("gt", ">"), ("ge", "≥"), ("lt", "<"), ("le", "≤"))


def limits_text(info: Any) -> str:
    """The bounds the field declares (``> 0``, ``≤ 1``)."""
    out = []
    for constraint in info.metadata:
        for attribute, sign in LIMIT_SIGNS:
            bound = getattr(constraint, attribute, None)
            if bound is not None:
                out.append(f"{sign} {value_text(bound)}")
    return ", ".join(out)


def cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


# -- the pages ---------------------------------------------------------------------------------
def heading(section: Section, family: str) -> str:
    if section.label == "":
        return "Top level"
    kinds = re.findall(r"\{([^}]*)\}", section.label)
    return f"`{plain_path(section.label)}`" + "".join(f" (kind: `{k}`)" for k in kinds)


def plain_path(label: str) -> str:
    """A section's path as written in a file (``leader.segments[]``, without the kind markers)."""
    return re.sub(r"\{[^}]*\}", "", label)


def anchor(section: Section, family: str) -> str:
    slug = re.sub(r"[^a-z0-9]+", "-", section.label.replace("[]", "-item").lower()).strip("-") or "top"
    return f"scenario-{family}-{slug}"


def docstring_text(model: type[BaseModel]) -> str:
    """The first paragraph of a class docstring, its reST markup made Markdown."""
    text = " ".join((model.__doc__ or "").strip().split("\n\n")[0].split())
    text = re.sub(r":[a-z]+:`~?\.?([^`]+)`", r"`\1`", text)
    return text.replace("``", "`").replace("\\ ", "")


def render_family(family: str, written: dict | None = None) -> str:
    """The field reference of one family (Markdown), every model class a section."""
    written = notes() if written is None else written
    fam = families()[family]
    tree = sections(fam.spec)
    links = {s.model: f"{{ref}}`{heading(s, family).replace('`', '')} <{anchor(s, family)}>`" for s in tree}
    lines: list[str] = []
    for section in tree:
        lines += [f"({anchor(section, family)})=", f"## {heading(section, family)}", ""]
        doc = docstring_text(section.model) if section.label else f"{fam.title} ({fam.paper})."
        if doc:
            lines += [doc, ""]
        if len(section.paths) > 1:
            lines += ["Also at " + ", ".join(f"`{plain_path(p)}`" for p in section.paths[1:]) + ".", ""]
        lines += ["| field | type | default | limits | unit | meaning |", "|---|---|---|---|---|---|"]
        for name, info in section.model.model_fields.items():
            unit, meaning = meaning_of(family, section.model, name, written) or ("", "")
            lines.append("| " + " | ".join(cell(t) for t in (
                f"`{name}`", type_text(info.annotation, links), default_text(info), limits_text(info), unit, meaning)) + " |")
        lines.append("")
    return "\n".join(lines)


def render_summary_keys(written: dict | None = None) -> str:
    """The summary keys: core keys with their meaning, then each family's results."""
    from robofleet.core.trace import CORE_SUMMARY_KEYS

    written = notes() if written is None else written
    core = written["summary"]
    lines = ["## Core keys (every family)", "", "| key | meaning |", "|---|---|"]
    lines += [f"| `{key}` | {cell(core.get(key, ''))} |" for key in CORE_SUMMARY_KEYS]
    for name, family in families().items():
        lines += ["", f"## {name} ({len(family.results)} keys)", "", "| key | meaning |", "|---|---|"]
        lines += [f"| `{key}` | {cell(meaning)} |" for key, meaning in family.results.items()]
    return "\n".join(lines) + "\n"


def render_reproductions() -> str:
    """The declared reproductions: name, family, paper, sweeps and the seeds of each budget."""
    from robofleet.experiments.reproductions import REPRODUCTIONS

    lines = ["| name | family | reproduces | sweeps | seeds per grid point |", "|---|---|---|---|---|"]
    for name, rep in REPRODUCTIONS.items():
        budgets = ", ".join(f"`{b}` {budget.seeds}" for b, budget in rep.budgets.items())
        sweeps = ", ".join(f"`{s}`" for s in rep.sweeps)
        lines.append("| " + " | ".join(cell(t) for t in (f"`{name}`", f"{{doc}}`{rep.family} </results/{rep.family}>`",
                                                          f"{rep.paper}: {rep.description}", sweeps, budgets)) + " |")
    return "\n".join(lines) + "\n"


def problems(written: dict | None = None) -> list[str]:
    """Fields without a meaning, meanings of fields that do not exist, core keys without one."""
    from robofleet.core.trace import CORE_SUMMARY_KEYS

    written = notes() if written is None else written
    out, known = [], set()
    for family, fam in families().items():
        for section in sections(fam.spec):
            for name in section.model.model_fields:
                known.add((section.model.__name__, name))
                known.add((declaring_class(section.model, name).__name__, name))
                if meaning_of(family, section.model, name, written) is None:
                    out.append(f"{family}: {plain_path(section.label) or 'top level'}.{name} ({section.model.__name__}) has no meaning in {NOTES_FILE.name}")
    for scope, classes in written.items():
        if scope == "summary":
            out += [f"summary: {key!r} is not a core summary key" for key in classes if key not in CORE_SUMMARY_KEYS]
            continue
        for klass, fields in classes.items():
            out += [f"{scope}: {klass}.{name} is written in {NOTES_FILE.name} but is no field of the specs"
                    for name in fields if (klass, name) not in known]
    out += [f"summary: core key {key!r} has no meaning" for key in CORE_SUMMARY_KEYS if key not in written.get("summary", {})]
    return out


def expand(text: str) -> str:
    """``text`` with every marker replaced by its generated reference."""
    lines = []
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith(FIELDS_MARK) and stripped.endswith("-->"):
            lines.append(render_family(stripped[len(FIELDS_MARK):-3].strip()))
        elif stripped == KEYS_MARK:
            lines.append(render_summary_keys())
        elif stripped == REPRODUCTIONS_MARK:
            lines.append(render_reproductions())
        else:
            lines.append(line)
    return "\n".join(lines) + "\n"


def setup(app):  # pragma: no cover - exercised by the docs build
    from sphinx.util import logging

    logger = logging.getLogger(__name__)

    def on_source_read(app, docname, source):
        if any(mark in source[0] for mark in (FIELDS_MARK, KEYS_MARK, REPRODUCTIONS_MARK)):
            source[0] = expand(source[0])

    def on_builder_inited(app):
        for problem in problems():
            logger.warning(f"scenario reference: {problem}")

    app.connect("source-read", on_source_read)
    app.connect("builder-inited", on_builder_inited)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
