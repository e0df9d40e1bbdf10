"""The proposed decentralized algorithm: sequential choices with rules (1) and (2).

Paper 002, Section 4.1 step 4 and Section 4.2 (step 5):

* **Choice order (step 4).** Robot ``j`` chooses before its communication neighbour ``i``
  when ``p_jx > p_ix`` or (``p_jy > p_iy`` and ``p_jx ≥ p_ix``); see
  :func:`robofleet.search.grids.choice_priority`. Each robot waits only for its
  higher-priority communication neighbours, so robots that do not wait on each other
  choose in the same *round*: round(i) = 1 + max round of the neighbours it waits for.
  Robots of one round are never neighbours, so their choices are independent and are
  computed together (vectorized); the result equals any sequential execution that keeps
  the order inside every neighbourhood.
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
stream. Complexity per step: O(rounds · m · k · n) for m robots per round and n robots per run.
"""

from __future__ import annotations

import numpy as np

from .grids import EPS
from .policy import StepContext, pick_uniform


def choice_rounds(rank: np.ndarray, links: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Round of every active robot in the sequential choice of step 4, per run.

    ``rank (R, n)``: choice priority of each robot's vertex (higher chooses first);
    ``links (R, n, n)``: communication neighbours; ``active (R, n)``. ``round[i] = 0`` when
    no higher-priority neighbour exists, else ``1 + max(round[j])`` over them (the longest
    waiting chain). Inactive robots get ``-1``.
    """
    n = rank.shape[-1]
    waits_for = links & (rank[:, None, :] > rank[:, :, None]) & active[:, None, :] & active[:, :, None]
    if not waits_for.any():
        return np.where(active, 0, -1)
    level = np.zeros(rank.shape, dtype=np.intp)
    for _ in range(n):
        new = np.where(waits_for, level[:, None, :] + 1, 0).max(axis=2, initial=0)
        if np.array_equal(new, level):
            break
        level = new
    return np.where(active, level, -1)


def neighbour_options(ctx: StepContext, robots: np.ndarray, choice: np.ndarray,
                      decided: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Options ``N_s,i(k)`` of ``robots`` from each one's own knowledge.

    Returns ``(candidates (m, k) vertex ids, options (m, k) bool, unvisited (m, k) bool)``.
    """
    here = ctx.pos[robots]
    cand = ctx.grid.candidates[here]
    words, masks = ctx.grid.candidate_words
    words, masks = words[here], masks[here]
    options = ctx.sensing.edge_sensed_ok[here] & ~ctx.maps.test_words(2, robots, words, masks)
    aware = ctx.rows(ctx.aware, robots)
    if aware.any():
        occupied = ((cand[:, :, None] == ctx.peers(ctx.pos, robots)[:, None, :]) & aware[:, None, :]).any(axis=-1)
        told = ctx.rows(ctx.links, robots) & ctx.peers(decided, robots)
        taken = ((cand[:, :, None] == ctx.peers(choice, robots)[:, None, :]) & told[:, None, :]).any(axis=-1)
        options &= ~occupied & ~taken
    unvisited = options & ~ctx.maps.test_words(0, robots, words, masks)
    return cand, options, unvisited


def farthest_from_average(ctx: StepContext, robots: np.ndarray, cand: np.ndarray, pool: np.ndarray,
                          choice: np.ndarray, decided: np.ndarray) -> np.ndarray:
    """Rule (2): keep the options at maximum distance from ``p_i,ave(k)`` (Definition 2.2)."""
    reported = np.where(decided, choice, ctx.pos)
    weights = ctx.rows(ctx.links, robots).astype(float)
    points = ctx.grid.points[ctx.peers(reported, robots)]
    p_ave = np.einsum("mn,mnd->md", weights, points) / weights.sum(axis=1, keepdims=True)
    d = np.linalg.norm(ctx.grid.points[cand] - p_ave[:, None, :], axis=-1)
    d = np.where(pool, d, -np.inf)
    return pool & (d >= d.max(axis=1, keepdims=True) - EPS)


class SequentialPolicy:
    """Sequential, collision-free choices: rules (1)&(2) (``repulsion=True``, the paper's
    algorithm) or rule (1) alone (``repulsion=False``, the 2016 algorithm "(1)&(3)")."""

    communicates = True
    collision_free = True

    def __init__(self, repulsion: bool):
        self.repulsion = repulsion

    def choose(self, ctx: StepContext) -> tuple[np.ndarray, np.ndarray]:
        """Steps 4–5 for all active robots; returns ``(choices (R·n,), rounds per run (R,))``."""
        choice = ctx.pos.copy()
        decided = ~ctx.active
        n = ctx.n
        per_run = choice_rounds(ctx.grid.priority[ctx.pos].reshape(-1, n), ctx.links, ctx.active.reshape(-1, n))
        rounds = per_run.ravel()
        u = ctx.streams.uniforms()
        n_rounds = int(rounds.max(initial=-1)) + 1
        for r in range(n_rounds):
            robots = np.flatnonzero(rounds == r)
            cand, options, unvisited = neighbour_options(ctx, robots, choice, decided)
            pool = np.where(unvisited.any(axis=1, keepdims=True), unvisited, options)
            if self.repulsion:
                social = ctx.rows(ctx.links, robots).any(axis=1)
                if social.any():
                    far = farthest_from_average(ctx, robots[social], cand[social], pool[social], choice, decided)
                    pool[social] = far
            choice[robots] = pick_uniform(cand, pool, u[robots], ctx.pos[robots])
            decided[robots] = True
            self.broadcast(ctx, robots, choice)
        return choice, per_run.max(axis=1) + 1

    @staticmethod
    def broadcast(ctx: StepContext, robots: np.ndarray, choice: np.ndarray) -> None:
        """The chooser adds its choice to its map and sends it to its neighbours (step 5)."""
        senders, local = np.nonzero(ctx.rows(ctx.links, robots))
        receivers = ctx.peer_ids(robots[senders], local)
        if len(senders):
            ctx.maps.set(0, np.concatenate([robots, receivers]), np.concatenate([choice[robots], choice[robots[senders]]]))
        else:
            ctx.maps.set(0, robots, choice[robots])
