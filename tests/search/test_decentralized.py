"""Unit evidence for steps 4–5: choice rounds, rules (1) and (2), own-map decisions."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robofleet.search.decentralized import SequentialPolicy, choice_rounds
from robofleet.search.knowledge import RobotMaps
from robofleet.search.policy import RobotStreams, StepContext
from robofleet.search.simulation import build_problem, run_search

from .helpers import small_spec


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 9).flatmap(lambda n: st.tuples(st.permutations(list(range(n))), st.lists(st.booleans(), min_size=n * n, max_size=n * n))))
def test_rounds_are_longest_waiting_chains(data):
    ranks, flags = data
    n = len(ranks)
    rank = np.asarray(ranks)
    links = np.asarray(flags, dtype=bool).reshape(n, n)
    links = links | links.T
    np.fill_diagonal(links, False)
    rounds = choice_rounds(rank[None], links[None], np.ones((1, n), dtype=bool))[0]
    # brute force: in decreasing priority, round = 1 + max round of higher linked robots
    expect = np.zeros(n, dtype=int)
    for i in np.argsort(-rank):
        higher = [j for j in range(n) if links[i, j] and rank[j] > rank[i]]
        expect[i] = 1 + max(expect[j] for j in higher) if higher else 0
    np.testing.assert_array_equal(rounds, expect)
    # robots of one round are never neighbours (their choices are independent)
    for r in np.unique(rounds):
        members = np.flatnonzero(rounds == r)
        assert not links[np.ix_(members, members)].any()


def context_for(spec, pos, seed=0, visited=()):
    problem = build_problem(spec, seed)
    grid = problem.grid
    n = len(pos)
    maps = RobotMaps(n, grid.n_vertices, len(problem.targets))
    for r, vs in visited:
        maps.set(0, np.full(len(vs), r), np.asarray(vs))
    pts = grid.points[pos]
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    links = d <= spec.ranges.r_c + 1e-9
    sensed = d <= spec.ranges.r_so + 1e-9
    return problem, StepContext(grid, problem.sensing, maps, RobotStreams([seed], n), np.asarray(pos), np.zeros(n),
                                np.ones(n, dtype=bool), links[None], sensed[None], (links | sensed)[None])


def interior_vertex(grid):
    free = np.flatnonzero(grid.edge_ok.all(axis=1))
    return free[len(free) // 2]


def test_rule1_prefers_unvisited():
    spec = small_spec(**{"robots.count": 1})
    grid = spec.built_grid()
    v = interior_vertex(grid)
    nb = grid.neighbours[v]
    unvisited = {int(nb[0]), int(nb[3])}
    seen = set()
    for seed in range(40):
        _, ctx = context_for(spec, [v], seed, visited=[(0, [w for w in nb if w not in unvisited])])
        choice, _ = SequentialPolicy(repulsion=False).choose(ctx)
        seen.add(int(choice[0]))
    assert seen == unvisited  # only unvisited options, and both of them (uniform)


def test_rule1_falls_back_to_visited_and_stays_when_boxed_in():
    spec = small_spec(**{"robots.count": 1})
    grid = spec.built_grid()
    v = interior_vertex(grid)
    nb = grid.neighbours[v]
    _, ctx = context_for(spec, [v], visited=[(0, list(nb))])
    choice, _ = SequentialPolicy(repulsion=False).choose(ctx)
    assert choice[0] in nb
    _, ctx = context_for(spec, [v])
    ctx.maps.set(2, np.zeros(6, dtype=int), nb)  # every neighbour known blocked
    choice, _ = SequentialPolicy(repulsion=False).choose(ctx)
    assert choice[0] == v


def test_rule2_picks_a_vertex_farthest_from_the_average():
    spec = small_spec(**{"robots.count": 2})
    grid = spec.built_grid()
    v = interior_vertex(grid)
    other = grid.neighbours[v][0]  # a neighbour one edge away
    for seed in range(20):
        _, ctx = context_for(spec, [v, other], seed)
        choice, rounds = SequentialPolicy(repulsion=True).choose(ctx)
        # the lower-priority robot chooses with p_ave = the other's choice or position
        hi, lo = (0, 1) if grid.priority[v] > grid.priority[other] else (1, 0)
        p_ave = grid.points[choice[hi]]
        here = ctx.pos[lo]
        opts = [w for w in grid.neighbours[here] if w >= 0 and w not in (ctx.pos[hi], choice[hi]) and grid.edge_ok[here][list(grid.neighbours[here]).index(w)]]
        dist = {w: np.linalg.norm(grid.points[w] - p_ave) for w in opts}
        assert np.isclose(dist[int(choice[lo])], max(dist.values()))
        assert rounds.tolist() == [2]
        assert choice[0] != choice[1]


def test_choice_depends_only_on_own_map():
    """Changing the map of a robot out of communication range does not change a robot's choice."""
    spec = small_spec(**{"robots.count": 2})
    grid = spec.built_grid()
    far = np.argsort(np.linalg.norm(grid.points - grid.points[0], axis=1))[-1]
    a, b = interior_vertex(grid), int(far)
    _, ctx1 = context_for(spec, [a, b], seed=3)
    _, ctx2 = context_for(spec, [a, b], seed=3, visited=[(1, list(range(grid.n_vertices)))])
    assert not ctx1.links[0, 0, 1]
    c1, _ = SequentialPolicy(True).choose(ctx1)
    c2, _ = SequentialPolicy(True).choose(ctx2)
    assert c1[0] == c2[0]


def test_single_robot_rules_coincide():
    """With one robot there is no neighbour: rule (2) reduces to rule (1), and RU is the same walk."""
    spec = small_spec(**{"robots.count": 1})
    res = [run_search(build_problem(spec, 7), alg, 7).results["search_time"] for alg in ("proposed", "rule1", "ru")]
    assert res[0] == res[1] == res[2]


def test_batched_runs_equal_separate_runs():
    """Lockstep batches are an execution detail: every run's results equal its separate run."""
    from robofleet.search.simulation import run_search_batch

    for alg, extra in (("proposed", {"random_failures": {"count": 1, "within_steps": 5}}), ("ru", {}), ("lfp", {})):
        spec = small_spec(**{"robots.count": 4, "algorithm": alg, "require_guarantee": False, **extra})
        seeds = [3, 14, 15, 92, 65]
        problems = [build_problem(spec, s) for s in seeds]
        batch = [o.results for o in run_search_batch(problems, alg, seeds)]
        assert batch == [run_search(p, alg, s).results for p, s in zip(problems, seeds)]
