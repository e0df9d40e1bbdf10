"""The proposed decentralized algorithm: sequential choices with rules (1) and (2).

Paper 002, Section 4.1 step 4 and Section 4.2 (step 5):

* **Choice order (step 4).** Robot ``j`` chooses before its communication neighbour ``i``
  when ``p_jx > p_ix`` or (``p_jy > p_iy`` and ``p_jx ≥ p_ix``); see
  :func:`robofleet.search.grids.choice_priority`. Each robot waits only for its
  higher-priority communication neighbours, so robots that do not wait on each other
  choose in the same *round*: round(i) = 1 + max round of the neighbours it waits for.
  Robots of one round are never neighbours, so their choices are independent; one
  compiled pass takes the robots round by round (:func:`.step_kernels.sequential_choices`),
  and the result equals any sequential execution that keeps the order inside every
  neighbourhood.
* **Options** ``N_s,i(k)``: lattice neighbours of the robot's vertex whose edge it senses
  free, minus the vertices it knows blocked, minus the current vertices of the robots it
  communicates with or senses, minus the choices already broadcast by earlier
  neighbours. ``V_u,i`` / ``V_v,i``: the unvisited / visited options in *its own map*.
* **Rule (1)** (no communication neighbour; the 2016 algorithm): a uniformly random vertex
  of ``V_u,i`` if non-empty, else of ``V_v,i``, else stay.
* **Rule (2)** (with communication neighbours; the repulsive force): ``p_i,ave(k)`` = mean of
  the choices of the neighbours that chose earlier and the positions of those that have not
  chosen yet; among ``V_u,i`` (else ``V_v,i``) keep the vertices at maximum distance from
  ``p_i,ave`` and pick one uniformly; stay if there is none.
* **Broadcast.** "After making the choice, rob_i adds it to its map and sends it to robots
  in N_c,i(k) and the receivers will update their maps": the chosen vertex becomes
  visited in the maps of the chooser and its neighbours, and later choosers exclude it.

Every quantity a robot uses is its own row: its map (:class:`~.knowledge.RobotMaps`), its
sensing at its vertex, the positions and choices its neighbours sent, and its own random
stream. Complexity per step: O(N log N + N · k · c) for N robots with at most
c neighbours each (the sparse relation of :mod:`robofleet.search.neighbours`); no all-pairs term.
"""

from __future__ import annotations

import numpy as np

from .neighbours import Neighbours, from_dense, longest_waiting_chain
from .policy import StepContext
from .step_kernels import sequential_choices


def choice_rounds(rank: np.ndarray, links: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Round of every active robot in the sequential choice of step 4, per run.

    ``rank (R, n)``: choice priority of each robot's vertex (higher chooses first);
    ``links (R, n, n)``: communication neighbours; ``active (R, n)``. ``round[i] = 0`` when
    no higher-priority neighbour exists, else ``1 + max(round[j])`` over them (the longest
    waiting chain). Inactive robots get ``-1``. (The dense front door of
    :func:`sparse_choice_rounds`.)
    """
    table = from_dense(links, np.zeros_like(links))
    return sparse_choice_rounds(rank.ravel(), table, active.ravel()).reshape(rank.shape)


def sparse_choice_rounds(rank: np.ndarray, table: Neighbours, active: np.ndarray) -> np.ndarray:
    """:func:`choice_rounds` over the sparse relation: ``(N,)`` rounds (O(N log N + L))."""
    return longest_waiting_chain(rank.astype(np.int64), table.start, table.peer, table.link, active)


class SequentialPolicy:
    """Sequential, collision-free choices: rules (1)&(2) (``repulsion=True``, the paper's
    algorithm) or rule (1) alone (``repulsion=False``, the 2016 algorithm "(1)&(3)")."""

    communicates = True
    collision_free = True

    def __init__(self, repulsion: bool):
        self.repulsion = repulsion

    def choose(self, ctx: StepContext) -> tuple[np.ndarray, np.ndarray]:
        """Steps 4–5 for all active robots (one compiled pass, :func:`.step_kernels.sequential_choices`);
        returns ``(choices (R·n,), rounds per run (R,))``."""
        grid, maps, nb = ctx.grid, ctx.maps, ctx.neighbours
        words, masks = grid.candidate_words
        choice = ctx.pos.copy()
        rounds = sequential_choices(ctx.pos, ctx.active, grid.priority, grid.candidates, words, masks,
                                    ctx.sensing.edge_sensed_ok, grid.points, maps.layers, maps.touched, maps.dirty,
                                    maps.unchecked, nb.start, nb.peer, nb.link, nb.aware, ctx.streams.uniforms(),
                                    self.repulsion, ctx.n, choice)
        return choice, rounds
