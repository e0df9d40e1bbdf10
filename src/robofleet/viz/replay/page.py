"""The replay page: one self-contained HTML file per scene.

The page's script and style are package data (``replay.js``, ``replay.css``,
``template.html``, read with :mod:`importlib.resources`); the scene is embedded as JSON
with its arrays deflated and base64-encoded. Nothing is fetched: the file works offline,
from any directory, without a server.
"""

from __future__ import annotations

import html
import json
import os
import sys
from importlib import resources
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from ...core.errors import ConfigError
from .scene import Scene


def asset(name: str) -> str:
    """The text of a packaged asset of the page (``replay.js``, ``replay.css``, ``template.html``)."""
    return resources.files(__package__).joinpath(name).read_text(encoding="utf-8")


def scene_json(scene: Scene) -> str:
    """The scene as JSON safe to embed in a ``<script>`` element."""
    text = json.dumps(scene.to_document(), separators=(",", ":"), allow_nan=False)
    return text.replace("</", "<\\/")


def replay_html(scene: Scene) -> str:
    """The complete page of ``scene``."""
    try:
        robofleet_version = version("robofleet")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree without metadata
        robofleet_version = "unknown"
    parts = {"__VERSION__": robofleet_version, "__TITLE__": html.escape(scene.title), "__CSS__": asset("replay.css"),
             "__JS__": asset("replay.js"), "__DATA__": scene_json(scene)}
    page = asset("template.html")
    for key in ("__VERSION__", "__TITLE__", "__CSS__", "__JS__"):
        page = page.replace(key, parts[key])
    return page.replace("__DATA__", parts["__DATA__"])  # last: the data may contain anything


def write_html(scene: Scene, path: str | Path) -> Path:
    """Write the page of ``scene`` to ``path`` (parent folders created); return the path.

    Raises
    ------
    ConfigError
        ``path`` cannot be written.
    """
    return write_page(replay_html(scene), path)


def write_page(text: str, path: str | Path) -> Path:
    """Write one HTML page to ``path`` (parent folders created); return the path, or raise
    :class:`ConfigError` naming it when it cannot be written."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: expected a writable file path, received one that cannot be written ({exc.strerror})") from None
    return path


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
