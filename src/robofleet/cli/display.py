"""Terminal display of results: rich tables of summaries and sweep means.

Values are shown as ``summary.json`` and the result store hold them: a missing value
(``None``, NaN, ±inf, pandas' ``NA``) reads ``null``, as the strict JSON writes it
(:func:`~robofleet.core.trace.dumps_json`), also inside lists and mappings.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

from rich.table import Table

from ..core.trace import to_plain

if TYPE_CHECKING:
    import pandas as pd

MIN_TABLE_COLUMNS = 3  # value columns shown however narrow the terminal
COLUMN_WIDTH = 11  # characters a numeric column needs to stay readable
PREFERRED_COLUMNS = ("success", "collisions", "min_pair_distance", "makespan", "mean_travel_time")


MISSING = "null"
"""How a missing value reads in a table: as the JSON summary writes it."""


def format_value(value: Any) -> str:
    """One table cell: a float to four significant digits, a missing value as ``null``,
    a list or mapping as its JSON text (missing values inside as ``null``)."""
    plain = to_plain(value, json_safe=True)  # numpy scalars to Python, NaN and ±inf to None
    if is_missing(plain):
        return MISSING
    if isinstance(plain, float):
        return f"{plain:.4g}"
    if isinstance(plain, (list, dict)):
        return json.dumps(plain, default=str, allow_nan=False)
    return str(plain)


def is_missing(value: Any) -> bool:
    """Whether ``value`` is a missing value: ``None``, or a scalar pandas counts as missing (NaN, ``NA``, ``NaT``)."""
    if value is None:
        return True
    import pandas as pd

    try:
        return bool(pd.api.types.is_scalar(value) and pd.isna(value))
    except (TypeError, ValueError):
        return False


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
