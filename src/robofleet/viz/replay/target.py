"""What ``robofleet view PATH`` was given: a run (directory or trace file) or a reproduction's output."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ...core.errors import ConfigError

TRACE_FILES = ("trace.json", "trace.npz")
REPRODUCTION_FILES = ("summary.csv", "table.md")


@dataclass(frozen=True)
class ViewTarget:
    """``kind`` is ``"run"`` (``directory`` holds trace.json + trace.npz) or
    ``"reproduction"`` (it holds summary.csv and table.md)."""

    kind: str
    directory: Path

    def default_output(self) -> Path:
        """Where the page goes unless told: ``replay.html`` in a run, ``report.html`` in a reproduction."""
        return self.directory / ("replay.html" if self.kind == "run" else "report.html")


def locate(path: str | Path) -> ViewTarget:
    """Classify ``path``.

    Raises
    ------
    ConfigError
        ``path`` does not exist or is neither a run nor a reproduction's output.
    """
    path = Path(path)
    if not path.exists():
        raise ConfigError(f"RUN: expected a run directory, a trace file or a reproduction's output, received {path}, which does not exist")
    directory = path.parent if path.is_file() and path.name in TRACE_FILES else path
    if directory.is_dir():
        if all((directory / name).is_file() for name in TRACE_FILES):
            return ViewTarget("run", directory)
        if all((directory / name).is_file() for name in REPRODUCTION_FILES):
            return ViewTarget("reproduction", directory)
        present = sorted(p.name for p in directory.iterdir())[:5]
        held = f"which holds {', '.join(present)}" if present else "which is empty"
        raise ConfigError(f"RUN: expected a run directory (trace.json, trace.npz) or a reproduction's output "
                          f"(summary.csv, table.md), received {directory}, {held}")
    raise ConfigError(f"RUN: expected a run directory, trace.json or trace.npz, or a reproduction's output, received the file {path}")
