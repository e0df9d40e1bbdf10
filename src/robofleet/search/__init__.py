"""Decentralized collision-free search of an unknown area on a grid (Yang 2017, X. Yang,
"Grid based 2D navigation by a decentralized robot system with collision avoidance",
CCC 2017).

The family contract: :mod:`.spec` (:class:`~.spec.Spec`, the scenario model, and the
four algorithms of Fig. 7), :mod:`.simulation` (steps 1–8 of Fig. 4, stop rules (3)/(4),
failures, through the core recorder; :func:`~.simulation.simulate`, and lockstep batches
of independent runs), :mod:`.metrics` (per-run results, ``success``), :mod:`.guarantees`
(Assumptions 2.1–3.1.3, Table 1, Theorem 4.1: :func:`~.guarantees.check`), :mod:`.family`
(``FAMILY``).

Algorithm parts (one module each): :mod:`.grids` (T/S/H grids, accessibility),
:mod:`.sensing` (r_so, r_st, r_c), :mod:`.knowledge` (per-robot maps and message
exchange), :mod:`.neighbours` (robots within r_c / r_so by spatial hashing, collisions), :mod:`.decentralized` (step-4 order, rules (1) and (2), broadcast),
:mod:`.policy` (per-robot random streams, step context), :mod:`.timing` (rotation +
trapezoidal translation), :mod:`.random_baseline` (RU), :mod:`.levy_flight` (LFP),
:mod:`.assumptions` (Assumptions 2.4, 2.5, 3.1.1–3.1.3), :mod:`.coverage` (detected share). The Fig. 7 reproduction is declared in
:mod:`robofleet.experiments.reproductions.search`.
"""

from ..core.lazy import exports

__all__ = [
    "LABELS",
    "Algorithm",
    "AssumptionReport",
    "Grid",
    "GridKind",
    "MotionTiming",
    "SearchOutcome",
    "SearchProblem",
    "Spec",
    "build_grid",
    "check",
    "check_assumptions",
    "run_search",
    "run_search_batch",
    "simulate",
]
__getattr__, __dir__ = exports(__name__, {
    ".assumptions": ["AssumptionReport", "check_assumptions"],
    ".grids": ["Grid", "GridKind", "build_grid"],
    ".guarantees": ["check"],
    ".simulation": ["SearchOutcome", "SearchProblem", "run_search", "run_search_batch", "simulate"],
    ".spec": ["LABELS", "Algorithm", "Spec"],
    ".timing": ["MotionTiming"],
})
