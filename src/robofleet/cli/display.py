"""Terminal display of results: rich tables of summaries and sweep means."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from rich.table import Table

if TYPE_CHECKING:
    import pandas as pd

MIN_TABLE_COLUMNS = 3  # value columns shown however narrow the terminal
COLUMN_WIDTH = 11  # characters a numeric column needs to stay readable
PREFERRED_COLUMNS = ("success", "collisions", "min_pair_distance", "makespan", "mean_travel_time")


def format_value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def key_value_table(mapping: dict, title: str) -> Table:
    table = Table(title=title)
    table.add_column("metric")
    table.add_column("value", justify="right")
    for key, value in mapping.items():
        table.add_row(str(key), format_value(value))
    return table


def frame_table(frame: pd.DataFrame, title: str, leading: int = 0, values: int = MIN_TABLE_COLUMNS) -> Table:
    """A rich table of a small DataFrame: its first ``leading`` columns (grid values,
    counts) and at most ``values`` more."""
    columns = list(frame.columns)
    shown = columns[: leading + values]
    note = "" if len(shown) == len(columns) else f" ({len(shown)} of {len(columns)} columns; all in the store)"
    table = Table(title=title + note)
    for column in shown:
        table.add_column(str(column), justify="right", overflow="fold")
    for row in frame[shown].itertuples(index=False):
        table.add_row(*(format_value(v) for v in row))
    return table
