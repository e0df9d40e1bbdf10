"""Sphinx configuration of the robofleet documentation (guide, theory and results pages
from docs/**/*.md, the API reference from the docstrings, the scenario and summary-key
references generated from the code by ``_ext/robofleet_reference.py``). Build: ``make docs``."""

import re
import sys
from importlib.metadata import version as installed_version
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

project = "robofleet"
author = "the robofleet authors"
release = installed_version("robofleet")
extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "myst_parser",
    "robofleet_reference",
    "outside_names",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_ext", "results/coordination"]
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True, "ignore-module-all": True}
napoleon_use_ivar = True
autodoc_member_order = "bysource"
autodoc_typehints = "description"
# Each API page lists its members in the summary tables at its top; keeping every function
# and class out of the tables of contents keeps the sidebar, which every page carries, to
# the pages and their sections (with them the site takes about 40 % longer to build).
toc_object_entries = False
autodoc_mock_imports = ["casadi"]
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
html_theme = "furo"
html_title = f"robofleet {release}"
nitpicky = False


TYPER_METADATA = re.compile(r"Annotated\[(.*?), <typer\.models\.\w+ object at 0x[0-9a-f]+>\]")
"""A CLI command's parameter type as autodoc writes it: the type with typer's option object."""


def cli_types_without_typer_objects(app, objtype, name, obj, options, args, retann):
    """The CLI commands' parameter types without typer's option objects, whose text is
    their memory address (``Annotated[bool, <typer.models.OptionInfo object at 0x…>]``
    becomes ``bool``); the options themselves are documented in the CLI reference."""
    for key, text in app.env.current_document.autodoc_annotations.get(name, {}).items():
        app.env.current_document.autodoc_annotations[name][key] = TYPER_METADATA.sub(r"\1", text)


def setup(app):
    app.connect("autodoc-process-signature", cli_types_without_typer_objects, priority=600)
