"""The replay page: one self-contained HTML file per scene.

The page's script and style are package data (``replay.js``, ``replay.css``,
``template.html``, read with :mod:`importlib.resources`); the scene is embedded as JSON
with its arrays deflated and base64-encoded. Nothing is fetched: the file works offline,
from any directory, without a server.

The template's placeholders (:data:`PLACEHOLDERS`) are filled in one pass over the
template (:func:`fill_template`): text put into the page (a scenario, team or robot named
``__DATA__``, a ``</script>`` in a name) is never read again as a placeholder, and the
embedded JSON has every ``<`` written ``\u003c``, so nothing in it can end or reopen the
``<script>`` element that holds it. Every page names its maker in its head
(:data:`GENERATOR`), which is how ``robofleet view`` knows a page it may replace.
"""

from __future__ import annotations

import html
import json
import os
import re
import sys
from collections.abc import Iterable, Iterator
from importlib import resources
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from ...core.errors import ConfigError
from ...core.files import replacing
from .scene import Scene

PLACEHOLDERS = re.compile(r"__(VERSION|TITLE|CSS|JS|DATA)__")
"""The placeholders of ``template.html``."""
GENERATOR = '<meta name="generator" content="robofleet'
"""The start of the tag every page robofleet writes carries in its head."""
GENERATOR_WITHIN = 2048
"""Bytes from the start of a page within which :data:`GENERATOR` is looked for."""


def asset(name: str) -> str:
    """The text of a packaged asset of the page (``replay.js``, ``replay.css``, ``template.html``)."""
    return resources.files(__package__).joinpath(name).read_text(encoding="utf-8")


def scene_json(scene: Scene) -> str:
    """The scene as JSON safe to embed in a ``<script>`` element: ``<`` only occurs inside
    JSON strings, where ``\\u003c`` stands for it, so no ``</script>`` or ``<!--`` remains."""
    return "".join(scene_json_pieces(scene))


def scene_json_pieces(scene: Scene) -> Iterator[str]:
    """:func:`scene_json` in pieces (one per top-level entry of the document), for writing
    without holding the whole text."""
    doc = scene.to_document()
    for index, (key, value) in enumerate(doc.items()):
        text = json.dumps({key: value}, separators=(",", ":"), allow_nan=False)[1:-1]
        yield ("{" if index == 0 else ",") + text.replace("<", "\\u003c")
    yield "}" if doc else "{}"


def robofleet_version() -> str:
    """The installed version (``unknown`` in a source tree without metadata)."""
    try:
        return version("robofleet")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree without metadata
        return "unknown"


def fill_template(template: str, parts: dict[str, str]) -> str:
    """``template`` with each placeholder replaced by ``parts[placeholder]``, in one pass:
    the inserted text is never searched for placeholders."""
    return PLACEHOLDERS.sub(lambda match: parts[match.group(0)], template)


def replay_html(scene: Scene) -> str:
    """The complete page of ``scene``."""
    return "".join(replay_html_pieces(scene))


def replay_html_pieces(scene: Scene) -> Iterator[str]:
    """The page of ``scene`` in pieces: the template's text and each placeholder's filling,
    in one pass over the template (as :func:`fill_template`), the data piece by piece."""
    parts = {"__VERSION__": html.escape(robofleet_version()), "__TITLE__": html.escape(scene.title), "__CSS__": asset("replay.css"),
             "__JS__": asset("replay.js")}
    template = asset("template.html")
    at = 0
    for match in PLACEHOLDERS.finditer(template):
        yield template[at:match.start()]
        if match.group(0) == "__DATA__":
            yield from scene_json_pieces(scene)
        else:
            yield parts[match.group(0)]
        at = match.end()
    yield template[at:]


def write_html(scene: Scene, path: str | Path) -> Path:
    """Write the page of ``scene`` to ``path`` (parent folders created); return the path.

    Raises
    ------
    ConfigError
        ``path`` cannot be written.
    """
    return write_page(replay_html_pieces(scene), path)


def write_page(text: str | Iterable[str], path: str | Path) -> Path:
    """Write one HTML page (its text, or its pieces one after the other) to ``path``
    (parent folders created; the file replaced only once complete,
    :func:`~robofleet.core.files.replacing`); return the path, or raise
    :class:`ConfigError` naming it when it cannot be written."""
    path = Path(path)
    try:
        with replacing(path) as temp, open(temp, "w", encoding="utf-8") as handle:
            for piece in [text] if isinstance(text, str) else text:
                handle.write(piece)
    except OSError as exc:
        raise ConfigError(f"{path}: expected a writable file path, received one that cannot be written ({exc.strerror})") from None
    return path


def is_robofleet_page(path: str | Path) -> bool:
    """Whether the file at ``path`` is a page robofleet wrote (:data:`GENERATOR` near its start)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(GENERATOR_WITHIN)
    except OSError:
        return False
    return GENERATOR.encode() in head


def can_open_browser() -> bool:
    """Whether a graphical browser can be started here (a display on Linux, and a browser
    that :mod:`webbrowser` knows)."""
    import webbrowser

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return False
    try:
        webbrowser.get()
    except webbrowser.Error:
        return False
    return True


def open_in_browser(path: str | Path) -> bool:
    """Open the page in the default browser when one can be started; whether it was."""
    import webbrowser

    return can_open_browser() and bool(webbrowser.open(Path(path).resolve().as_uri()))
