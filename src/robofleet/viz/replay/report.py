"""One self-contained HTML report of a reproduction's output: its tables (``table.md``)
and its figures (every ``*.png`` and ``*.gif``, embedded), nothing fetched."""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

from ...core.errors import ConfigError
from .page import GENERATOR, robofleet_version, write_page

FIGURE_SUFFIXES = {".png": "image/png", ".gif": "image/gif"}
STYLE = """body{font:14px/1.45 system-ui,sans-serif;color:#222;max-width:1200px;margin:0 auto;padding:12px 20px}
h1{font-size:20px}h2{font-size:16px;margin-top:28px}table{border-collapse:collapse;margin:8px 0 16px;font-size:12.5px}
td,th{border:1px solid #ccc;padding:2px 7px;text-align:right}th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}
figure{margin:12px 0 24px}figure img{max-width:100%;border:1px solid #ddd}figcaption{color:#555;font-size:12px}
code{background:#f3f3f3;padding:0 3px}.meta{color:#666}"""


def inline_markdown(text: str) -> str:
    """Escaped text with ``code`` and **bold** spans."""
    text = html.escape(text)
    text = re.sub(r"`([^`]+)`", r"<code>\1</code>", text)
    return re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", text)


def table_html(rows: list[str]) -> str:
    """A pipe table (header, separator, body rows) as HTML."""
    cells = [[c.strip() for c in row.strip().strip("|").split("|")] for row in rows]
    body = [r for r in cells[1:] if not all(re.fullmatch(r":?-{2,}:?", c) for c in r if c)]
    head = "".join(f"<th>{inline_markdown(c)}</th>" for c in cells[0])
    lines = "".join("<tr>" + "".join(f"<td>{inline_markdown(c)}</td>" for c in r) + "</tr>" for r in body)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{lines}</tbody></table>"


def markdown_html(text: str) -> str:
    """The subset of markdown ``table.md`` uses: headings, paragraphs and pipe tables."""
    out, paragraph, table = [], [], []

    def flush() -> None:
        if paragraph:
            out.append(f"<p>{inline_markdown(' '.join(paragraph))}</p>")
            paragraph.clear()
        if table:
            out.append(table_html(table))
            table.clear()

    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("|"):
            if paragraph:
                out.append(f"<p>{inline_markdown(' '.join(paragraph))}</p>")
                paragraph.clear()
            table.append(stripped)
        elif not stripped:
            flush()
        elif stripped.startswith("#"):
            flush()
            level = min(6, len(stripped) - len(stripped.lstrip("#")) + 1)
            out.append(f"<h{level}>{inline_markdown(stripped.lstrip('#').strip())}</h{level}>")
        else:
            if table:
                flush()
            paragraph.append(stripped)
    flush()
    return "\n".join(out)


def figure_html(path: Path) -> str:
    """An embedded figure with its file name as caption."""
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return (f'<figure><img alt="{html.escape(path.stem)}" src="data:{FIGURE_SUFFIXES[path.suffix.lower()]};base64,{data}">'
            f"<figcaption>{html.escape(path.name)}</figcaption></figure>")


def report_html(directory: str | Path, title: str | None = None) -> str:
    """The report page of the reproduction written into ``directory``."""
    directory = Path(directory)
    try:
        tables = (directory / "table.md").read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{directory / 'table.md'}: expected a readable reproduction table, received an unreadable file ({exc.strerror})") from None
    figures = sorted(p for p in directory.iterdir() if p.suffix.lower() in FIGURE_SUFFIXES)
    runs = sorted(p.name for p in (directory / "runs").iterdir() if p.is_dir()) if (directory / "runs").is_dir() else []
    name = title or directory.resolve().name
    meta = f"sweeps: {', '.join(runs)}" if runs else ""
    body = [f"<h1>{html.escape(name)}: reproduction report</h1>", f'<p class="meta">{html.escape(meta)}</p>' if meta else "",
            "<h2>Tables</h2>", markdown_html(tables), "<h2>Figures</h2>"]
    body += [figure_html(p) for p in figures] or ["<p>No figures were written.</p>"]
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">{GENERATOR} {html.escape(robofleet_version())}">'
            f"<title>{html.escape(name)}</title>"
            f"<style>{STYLE}</style></head><body>" + "\n".join(body) + "</body></html>")


def write_report(directory: str | Path, path: str | Path) -> Path:
    """Write :func:`report_html` of ``directory`` to ``path``; return the path."""
    return write_page(report_html(directory), path)
