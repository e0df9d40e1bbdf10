"""What every figure, animation and replay page of a run shares without drawing: its
title and the steps it shows as frames. Imports no plotting library."""

from __future__ import annotations

from ..core.trace import Trace


def frame_indices(n_steps: int, max_frames: int = 150) -> list[int]:
    """At most ``max_frames`` evenly spaced step indices, always including the last."""
    if n_steps <= max_frames:
        return list(range(n_steps))
    stride = -(-n_steps // max_frames)
    idx = list(range(0, n_steps, stride))
    if idx[-1] != n_steps - 1:
        idx.append(n_steps - 1)
    return idx


def method_of(trace: Trace) -> str:
    """The method a run used, as its family records it (``method``, else ``algorithm`` and scheduler)."""
    md = trace.metadata
    if md.get("method"):
        return str(md["method"])
    algorithm = md.get("algorithm_label") or md.get("algorithm")
    if isinstance(algorithm, dict):
        algorithm = algorithm.get("kind")
    scheduler = md.get("scheduler")
    if isinstance(scheduler, dict):
        scheduler = str(scheduler.get("kind", "")).upper()
    return " · ".join(str(p) for p in (algorithm, scheduler) if p)


def run_title(trace: Trace) -> str:
    """``scenario · method · seed S``: the title every figure and animation of a run starts with."""
    parts = [trace.scenario or trace.family, method_of(trace)]
    seed = trace.metadata.get("seed")
    return " · ".join(p for p in parts if p) + (f" · seed {seed}" if seed is not None else "")
