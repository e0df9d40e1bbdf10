"""Markdown tables of result frames, shared by every reproduction."""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import pandas as pd


def markdown_table(frame: pd.DataFrame, columns: Sequence[str] | None = None, formats: Mapping[str, str] | None = None) -> str:
    """Rows of ``frame`` as a markdown table.

    ``formats`` maps a column to a format spec (``".0%"``, ``".1e"``, ``"d"`` for
    integers...); other float columns use ``".3g"``. Missing or non-finite values print
    as ``–``. Headers are the column names with underscores as spaces.
    """
    cols = list(columns) if columns is not None else list(frame.columns)
    formats = dict(formats or {})
    lines = ["| " + " | ".join(str(c).replace("_", " ") for c in cols) + " |", "|" + "---|" * len(cols)]
    for _, row in frame.iterrows():
        lines.append("| " + " | ".join(_cell(row[c], formats.get(c)) for c in cols) + " |")
    return "\n".join(lines)


def _cell(value, spec: str | None) -> str:
    if isinstance(value, (float, np.floating)) and not np.isfinite(value):
        return "–"
    if value is None or value is pd.NA:
        return "–"
    if spec == "d":
        return str(int(value))
    if spec is not None:
        return format(value, spec)
    if isinstance(value, (float, np.floating)):
        return format(value, ".3g")
    return str(value)
