"""Compiled per-step kernels of the search loop: one call per phase of a step.

Small teams on the ~10² vertices of the Fig. 7 area spend a step on a few dozen robots'
table look-ups, so a step is dominated by the number of array calls rather than by the
work. Each kernel here performs one phase of Fig. 4 for every robot of a batch in a single
compiled pass, with exactly the arithmetic of the vectorized definitions it replaces:

* :func:`sequential_choices` — steps 4–5 of the proposed algorithm and of "(1)&(3)"
  (:mod:`.decentralized`): rounds, options ``N_s,i(k)``, rules (1)/(2), the uniform pick
  and the broadcast of each choice. Robots are taken round by round; robots of one round
  are never communication neighbours, so the result is the round-wise one;
* :func:`random_unvisited_choices` — RU's simultaneous rule (1) (:mod:`.random_baseline`);
* :func:`levy_choices` — the grid-adapted LFP move (:mod:`.levy_flight`), headings given;
* :func:`sense_and_record` — steps 1–2 (:func:`.loop_kernels.observe`);
* :func:`may_collide` — the observer's cheap pre-check for collisions of a move;
* :func:`advance_clocks` — the step duration of fixed rotation (:mod:`.timing`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .grids import EPS
from .knowledge import set_bit
from .neighbours import longest_waiting_chain


@numba.njit(cache=True, inline="always")
def robot_options(i, here, cand, words, masks, sensed_ok, layers, start, peer, aware, link, pos, choice, decided,
                  check_peers, options, unvisited):
    """Options ``N_s,i(k)`` of robot ``i`` on ``here`` into ``options (k,)`` and ``unvisited (k,)``;
    returns how many are unvisited. Without ``check_peers`` the other robots are ignored (RU)."""
    n_unvisited = 0
    for s in range(cand.shape[1]):
        c = cand[here, s]
        ok = sensed_ok[here, s] and (layers[i, 2, words[here, s]] & masks[here, s]) == 0
        if ok and check_peers:
            for e in range(start[i], start[i + 1]):
                j = peer[e]
                if (aware[e] and c == pos[j]) or (link[e] and decided[j] and c == choice[j]):
                    ok = False
        options[s] = ok
        unvisited[s] = ok and (layers[i, 0, words[here, s]] & masks[here, s]) == 0
        n_unvisited += unvisited[s]
    return n_unvisited


@numba.njit(cache=True, inline="always")
def pick_slot(pool, u):
    """Slot ``⌊u · |pool|⌋`` among the true entries of ``pool`` (``-1`` if none): the uniform
    choice "with prob. ``1/|V|``" of rules (1) and (2) (as :func:`.policy.pick_uniform`)."""
    count = 0
    for s in range(len(pool)):
        count += pool[s]
    if count == 0:
        return -1
    index = min(int(u * count), count - 1)
    for s in range(len(pool)):
        if pool[s]:
            if index == 0:
                return s
            index -= 1
    return -1


@numba.njit(cache=True, inline="always")
def keep_farthest(i, here, cand, points, start, peer, link, pos, choice, decided, pool):
    """Rule (2) on ``pool``: keep the options at maximum distance from ``p_i,ave(k)``, the mean of
    the linked peers' choices (those that chose) or positions (the others), as
    :func:`.decentralized.farthest_from_average`."""
    ax = ay = 0.0
    count = 0
    for e in range(start[i], start[i + 1]):
        if link[e]:
            j = peer[e]
            v = choice[j] if decided[j] else pos[j]
            ax += points[v, 0]
            ay += points[v, 1]
            count += 1
    ax /= count
    ay /= count
    d = np.full(len(pool), -np.inf)
    best = -np.inf
    for s in range(len(pool)):
        if pool[s]:
            dx, dy = points[cand[here, s], 0] - ax, points[cand[here, s], 1] - ay
            d[s] = math.sqrt(dx * dx + dy * dy)
            best = max(best, d[s])
    for s in range(len(pool)):
        pool[s] = pool[s] and d[s] >= best - EPS


@numba.njit(cache=True)
def sequential_choices(pos, active, priority, cand, words, masks, sensed_ok, points, layers, touched, dirty, unchecked,
                       start, peer, link, aware, u, repulsion, n, choice):
    """Steps 4–5 of every active robot into ``choice`` (preset to ``pos``); returns the choice
    rounds of each run of ``n`` robots (1 + its largest round, 0 without active robots).
    Each choice is broadcast: visited in the chooser's map and in its communication
    neighbours' maps."""
    level = longest_waiting_chain(priority[pos].astype(np.int64), start, peer, link, active)
    decided = ~active
    k = cand.shape[1]
    options, unvisited = np.empty(k, np.bool_), np.empty(k, np.bool_)
    for i in np.argsort(level, kind="mergesort"):
        if level[i] < 0:
            continue
        here = pos[i]
        n_unvisited = robot_options(i, here, cand, words, masks, sensed_ok, layers, start, peer, aware, link, pos,
                                    choice, decided, True, options, unvisited)
        pool = unvisited if n_unvisited else options
        social = False
        for e in range(start[i], start[i + 1]):
            social |= link[e]
        if repulsion and social:
            keep_farthest(i, here, cand, points, start, peer, link, pos, choice, decided, pool)
        slot = pick_slot(pool, u[i])
        choice[i] = cand[here, slot] if slot >= 0 else here
        decided[i] = True
        set_bit(layers, touched, dirty, unchecked, 0, i, choice[i])
        for e in range(start[i], start[i + 1]):
            if link[e]:
                set_bit(layers, touched, dirty, unchecked, 0, peer[e], choice[i])
    rounds = np.zeros(len(pos) // n, np.int64)
    for i in range(len(pos)):
        rounds[i // n] = max(rounds[i // n], level[i] + 1)
    return rounds


@numba.njit(cache=True)
def random_unvisited_choices(robots, pos, cand, words, masks, sensed_ok, layers, touched, dirty, unchecked, u, choice):
    """RU: rule (1) from each of ``robots``' own map, ignoring the other robots, into ``choice``;
    the choice is visited in the chooser's map."""
    k = cand.shape[1]
    options, unvisited = np.empty(k, np.bool_), np.empty(k, np.bool_)
    none = np.zeros(1, np.int64)
    flags = np.zeros(0, np.bool_)
    for i in robots:
        here = pos[i]
        n_unvisited = robot_options(i, here, cand, words, masks, sensed_ok, layers, none, none, flags, flags, pos,
                                    choice, flags, False, options, unvisited)
        slot = pick_slot(unvisited if n_unvisited else options, u[i])
        choice[i] = cand[here, slot] if slot >= 0 else here
    for i in robots:
        set_bit(layers, touched, dirty, unchecked, 0, i, choice[i])


@numba.njit(cache=True)
def levy_choices(robots, pos, cand, words, masks, sensed_ok, layers, start, peer, sensed, any_sensed, points,
                 edge_units, wall_push, cos_h, sin_h, repulsion, remaining, choice):
    """LFP: each of ``robots`` (heading ``(cos_h, sin_h)``) takes the option closest in direction
    to its heading plus the repulsion of sensed robots and sensed blocked edges
    (:meth:`.levy_flight.LevyFlightPolicy.choose`). Returns the edge slot taken per robot and
    whether it slides (no option within 90°); ``remaining`` counts down, 0 when stuck."""
    m, k = len(robots), cand.shape[1]
    options, unvisited = np.empty(k, np.bool_), np.empty(k, np.bool_)
    never = np.zeros(len(pos), np.bool_)
    best_slot, slide = np.full(m, -1, np.int64), np.zeros(m, np.bool_)
    for r in range(m):
        i = robots[r]
        here = pos[i]
        robot_options(i, here, cand, words, masks, sensed_ok, layers, start, peer, sensed, sensed, pos, pos, never,
                      any_sensed, options, unvisited)
        px, py = wall_push[here, 0], wall_push[here, 1]
        if any_sensed:
            qx = qy = 0.0
            for e in range(start[i], start[i + 1]):
                j = peer[e]
                ex, ey = points[pos[i], 0] - points[pos[j], 0], points[pos[i], 1] - points[pos[j], 1]
                d2 = ex * ex + ey * ey
                if sensed[e] and d2 > 0:
                    inv = 1.0 / d2
                    qx += inv * ex
                    qy += inv * ey
            px, py = px + qx, py + qy
        dx, dy = cos_h[r] + repulsion * px, sin_h[r] + repulsion * py
        best, score = 0, -np.inf
        for s in range(k):
            value = edge_units[here, s, 0] * dx + edge_units[here, s, 1] * dy if options[s] else -np.inf
            if value > score:
                best, score = s, value
        if options[best]:
            choice[i] = cand[here, best]
            best_slot[r], slide[r] = best, score <= 0
            remaining[i] -= 1
        else:
            choice[i] = here
            remaining[i] = 0
    return best_slot, slide


@numba.njit(cache=True)
def sense_and_record(live, pos, n, visited, target_visible, targets, cand, sensed_ok, inaccessible, layers, touched,
                     dirty, unchecked, blocked_visited):
    """Steps 1–2 for the ``live`` robots: the observer's visits, target sensing and its broadcast
    to every live robot of the run, and step 2 in each robot's own map (its vertex visited
    and sensed, neighbours discovered or blocked — blocked ones also visited when
    ``blocked_visited``). Returns, per target, the first live robot that finds it while no
    robot knew it (``-1`` otherwise): the ``target_found`` events."""
    n_targets = target_visible.shape[1]
    finder = np.full(n_targets, -1, np.int64)
    known = np.zeros(n_targets, np.bool_)
    for i in range(len(targets)):
        for t in range(n_targets):
            known[t] |= targets[i, t]
    found = np.zeros((visited.shape[0], n_targets), np.bool_)
    for i in live:
        here = pos[i]
        visited[i // n, here] = True
        for t in range(n_targets):
            if target_visible[here, t]:
                found[i // n, t] = True
                if finder[t] < 0 and not known[t]:
                    finder[t] = i
    for i in live:
        for t in range(n_targets):
            targets[i, t] |= found[i // n, t]
        here = pos[i]
        set_bit(layers, touched, dirty, unchecked, 0, i, here)
        set_bit(layers, touched, dirty, unchecked, 3, i, here)
        for s in range(cand.shape[1]):
            if sensed_ok[here, s]:
                set_bit(layers, touched, dirty, unchecked, 1, i, cand[here, s])
            if inaccessible[here, s]:
                set_bit(layers, touched, dirty, unchecked, 2, i, cand[here, s])
                if blocked_visited:
                    set_bit(layers, touched, dirty, unchecked, 0, i, cand[here, s])
    return finder


@numba.njit(cache=True)
def may_collide(pos, choice, n):
    """Cheap pre-check of a move: a repeated destination in a run, or a robot moving onto a
    vertex occupied in its run."""
    N = len(pos)
    for i in range(N):
        first = (i // n) * n
        for j in range(first, min(first + n, N)):
            if j != i and (choice[j] == choice[i] or (choice[i] != pos[i] and choice[i] == pos[j])):
                return True
    return False


@numba.njit(cache=True)
def advance_clocks(pos, choice, running, rounds, per_run, n, decision_seconds, penalty, step_seconds, time, total_rounds):
    """Fixed rotation: each running run's clock advances by its choice rounds, its collision
    penalties and one rotation plus translation if any of its robots moves (:mod:`.timing`)."""
    for r in range(len(time)):
        moved = False
        for i in range(r * n, (r + 1) * n):
            moved |= choice[i] != pos[i]
        dt = decision_seconds * rounds[r] + penalty * per_run[r] + step_seconds * (1.0 if moved else 0.0)
        if running[r]:
            time[r] += dt
            total_rounds[r] += rounds[r]
