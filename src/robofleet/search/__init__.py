"""Decentralized collision-free search of an unknown area on a grid (paper 002, X. Yang,
"Grid based 2D navigation by a decentralized robot system with collision avoidance",
CCC 2017).

Parts (one module each): :mod:`.grids` (T/S/H grids, accessibility), :mod:`.sensing`
(r_so, r_st, r_c), :mod:`.knowledge` (per-robot maps and message exchange),
:mod:`.decentralized` (step-4 order, rules (1) and (2), broadcast), :mod:`.simulation`
(steps 1–8, stop rules (3)/(4), failures; single runs or lockstep batches of independent
runs), :mod:`.policy` (per-robot random streams, step context), :mod:`.timing` (rotation +
trapezoidal translation), :mod:`.random_baseline` (RU), :mod:`.levy_flight` (LFP),
:mod:`.assumptions` (Assumptions 2.4, 2.5, 3.1.1–3.1.3), :mod:`.coverage` (detected share),
:mod:`.scenario` (Spec, simulate), :mod:`.reproduce` (Fig. 7 and the coverage study).
"""

from .assumptions import AssumptionReport, check_assumptions
from .grids import Grid, GridKind, build_grid
from .simulation import LABELS, Algorithm, SearchOutcome, SearchProblem, run_search, run_search_batch
from .timing import MotionTiming

__all__ = [
    "AssumptionReport", "check_assumptions", "Grid", "GridKind", "build_grid", "LABELS", "Algorithm",
    "SearchOutcome", "SearchProblem", "run_search", "run_search_batch", "MotionTiming",
]
