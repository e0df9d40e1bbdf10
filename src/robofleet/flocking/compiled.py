"""Compiled ASYNC Look-Compute-Move cycles (numba) for Algorithm 1 and its Sec. 5-6.4 variants.

:class:`~robofleet.flocking.schedulers.LookComputeMove` hands a run of ASYNC events (Look
time, follower, cycle length τ, rigidity draw η, leader position) to :func:`run_events`,
which performs, per event and in one compiled loop, exactly the interpreted steps:

* Look (:func:`robofleet.flocking.model.look`): every follower's position at the Look
  (interpolated along its Move), the other followers in the observer's frame (unsorted:
  nothing below depends on their order);
* Compute (:meth:`robofleet.flocking.basic.BasicAlgorithm.decide`): lines 1-2 (B, Y,
  footnote-3 wait), lines 3-14 (S_j, ranks), lines 15-38 (the case analysis) with the
  pattern's slot order F_0, F_1, F_2 computed once per run
  (:meth:`~robofleet.flocking.basic.BasicAlgorithm.slot_order`), and the Move of the
  basic, stripe (Sec. 5.3, :func:`~robofleet.flocking.stripe.first_exit`), hula-hoop
  (Sec. 5.2, straight or along :func:`~robofleet.flocking.hula_hoop.spiral`) and
  randomized (Sec. 6.4, when no tie calls for a random choice) algorithms;
* Move (A2): ℓ = min(``|path|``, max(δ_f, η v_f τ)), the new Move stored, the end point and
  the cycle-log row written.

Ranks are counted instead of sorted: the rank k of the observer in S_j is one plus the
number of followers of S_j whose sort key (line 13) is lexicographically larger; the
rank in H (line 24) and the stable-space neighbours (Figs. 12-13) follow from the same
counts, and the barycenter is the correctly rounded sum (:func:`exact_sum`, as
:func:`robofleet.flocking.basic.barycenter`), which no order changes. Every other
floating-point expression is the interpreted one, term by term (no fused multiply-add),
so the two engines give bit-identical traces.

An event the compiled loop does not cover stops it (return value ``< n_events``): a
randomized tie, which draws a coin or a uniform choice from the algorithm's stream (the
loop hands back every event where such a tie may arise). The engine runs that event
interpreted and resumes.
"""

from __future__ import annotations

import math

import numba
import numpy as np

BASIC, STRIPE, HULA_HOOP, RANDOMIZED = 0, 1, 2, 3
#: Status of the Compute of one event: a straight Move, the footnote-3 wait, "run it
#: interpreted", or a hula-hoop spiral Move.
SLOT, WAIT, INTERPRETED, SPIRAL = 0, 1, 2, 3


@numba.njit(cache=True, inline="always")
def point_at(path, cum, j, s):
    """Follower ``j`` after ``s`` along its path, as :meth:`schedulers._Motion.positions`
    computes it (0 ≤ s ≤ ℓ)."""
    seg = 0
    for q in range(1, cum.shape[1] - 1):
        if cum[j, q] < s:
            seg += 1
        else:
            break
    c0, c1 = cum[j, seg], cum[j, seg + 1]
    frac = (s - c0) / (c1 - c0) if c1 > c0 else 0.0
    ax, ay = path[j, seg, 0], path[j, seg, 1]
    return ax + frac * (path[j, seg + 1, 0] - ax), ay + frac * (path[j, seg + 1, 1] - ay)


@numba.njit(cache=True)
def _look_positions(path, cum, t0, travel, speed, rest, i, t, wx, wy):
    """Every follower's position at time ``t`` into ``wx``, ``wy`` (``rest[j]``, its point at
    ℓ, once its Move is over); returns how many followers other than ``i`` are moving."""
    seen = 0
    for j in range(len(speed)):
        v = speed[j] * (t - t0[j])
        if v >= travel[j]:
            wx[j], wy[j] = rest[j, 0], rest[j, 1]
        else:
            wx[j], wy[j] = point_at(path, cum, j, max(v, 0.0))
            if j != i and t0[j] < t:
                seen += 1
    return seen


@numba.njit(cache=True, inline="always")
def _end_position(path, cum, t0, travel, speed, j, t):
    """Follower ``j`` at time ``t`` as :meth:`schedulers._Motion.position_of` computes it."""
    s = min(max(speed[j] * (t - t0[j]), 0.0), travel[j])
    n = cum.shape[1]
    seg = n
    for q in range(n):
        if cum[j, q] >= s:
            seg = q
            break
    seg = max(min(seg, n - 1), 1)
    c0, c1 = cum[j, seg - 1], cum[j, seg]
    frac = (s - c0) / (c1 - c0) if c1 > c0 else 0.0
    ax, ay = path[j, seg - 1, 0], path[j, seg - 1, 1]
    return ax + frac * (path[j, seg, 0] - ax), ay + frac * (path[j, seg, 1] - ay)


@numba.njit(cache=True)
def exact_sum(values):
    """The correctly rounded sum of finite ``values`` (what :func:`math.fsum` returns),
    whatever their order.

    Fast path: the compensated sum s + c of Ogita, Rump & Oishi's Sum2 (error-free
    TwoSum per term, the errors summed in c) is within γ_{n−1}γ_{n−2} Σ|x| of the exact
    sum, so T = fl(s + c) is its correct rounding whenever that bound plus the rounding
    error of T stays short of half the gap to T's neighbours. Otherwise (the exact sum
    lies within that bound of a rounding midpoint) :func:`partials_sum` decides.
    """
    s = c = a = 0.0
    for v in values:
        t = s + v
        bp = t - s
        c += (s - (t - bp)) + (v - bp)
        s = t
        a += abs(v)
    total = s + c
    bp = total - s
    r = (s - (total - bp)) + (c - bp)                           # total + r = s + c exactly
    g = len(values) * 2.0**-53
    bound = 4.0 * (g / (1.0 - g)) ** 2 * a
    half_gap = 0.5 * min(np.nextafter(total, math.inf) - total, total - np.nextafter(total, -math.inf))
    if math.isfinite(total) and half_gap - abs(r) > bound:
        return total
    return partials_sum(values)


@numba.njit(cache=True)
def partials_sum(values):
    """The correctly rounded sum of finite ``values``: Shewchuk's non-overlapping
    partials (at most one more per value), then round-half-even of their sum."""
    partials = np.empty(len(values) + 1)
    n = 0
    for v in values:
        x = v
        k = 0
        for q in range(n):
            y = partials[q]
            if abs(x) < abs(y):
                x, y = y, x
            hi = x + y
            lo = y - (hi - x)
            if lo != 0.0:
                partials[k] = lo
                k += 1
            x = hi
        partials[k] = x
        n = k + 1
    if n == 0:
        return 0.0
    n -= 1
    hi = partials[n]
    lo = 0.0
    while n > 0:
        x = hi
        n -= 1
        y = partials[n]
        hi = x + y
        lo = y - (hi - x)
        if lo != 0.0:
            break
    if n > 0 and ((lo < 0.0 and partials[n - 1] < 0.0) or (lo > 0.0 and partials[n - 1] > 0.0)):
        y = lo * 2.0                     # halfway case: the partials below decide the rounding
        x = hi + y
        if y == x - hi:
            hi = x
    return hi


@numba.njit(cache=True, inline="always")
def _side(lateral, tolerance):
    """:func:`robofleet.flocking.basic.side_labels` of one follower: 0 on Y, 1 left, 2 right."""
    return 0 if abs(lateral) <= tolerance else (1 if lateral > 0 else 2)


@numba.njit(cache=True, inline="always")
def _key(kind, c, x, y, lx, ly, bx, by, ax, ay):
    """Sort key ``c`` (0 = primary) of the follower at local (x, y): line 13's dist(L, ·),
    dist(B, ·), then x, y (:meth:`BasicAlgorithm.robot_keys`); the stripe algorithm puts
    dist(Y, ·) first (:meth:`StripeAlgorithm.robot_keys`)."""
    if kind == STRIPE:
        if c == 0:
            return abs((x - lx) * -ay + (y - ly) * ax)
        c -= 1
    if c == 0:
        dx, dy = x - lx, y - ly
        return math.sqrt(dx * dx + dy * dy)
    if c == 1:
        dx, dy = x - bx, y - by
        return math.sqrt(dx * dx + dy * dy)
    return x if c == 2 else y


@numba.njit(cache=True)
def _ranks_before(kind, x, y, lx, ly, bx, by, ax, ay):
    """Whether the follower at (x, y) ranks strictly before the observer (at the origin):
    its keys lexicographically larger (:func:`robofleet.flocking.basic.sort_descending`;
    on equal keys the observer, listed first, ranks first)."""
    for c in range(5 if kind == STRIPE else 4):
        a = _key(kind, c, x, y, lx, ly, bx, by, ax, ay)
        b = _key(kind, c, 0.0, 0.0, lx, ly, bx, by, ax, ay)
        if a != b:
            return a > b
    return False


@numba.njit(cache=True, inline="always")
def _tied(d_leader, my_d_leader, x, y, bx, by, tol):
    """Whether the follower at (x, y), at ``d_leader`` from L, is within ``tol`` of the
    observer on dist(L, ·) and dist(B, ·) (Sec. 6.4 case b, :meth:`RandomizedAlgorithm.rank_in_h`)."""
    if abs(d_leader - my_d_leader) > tol:
        return False
    ex, ey = x - bx, y - by
    return abs(math.sqrt(ex * ex + ey * ey) - math.sqrt(bx * bx + by * by)) <= tol


@numba.njit(cache=True, inline="always")
def _pick(slots, n_slots, j, index, own):
    """:meth:`BasicAlgorithm._pick`: the ``index``-th slot of F_j, clamped; empty F_j falls back."""
    for jj in (j, 0, own, 3 - own):
        n = n_slots[jj]
        if n > 0:
            return slots[jj, min(max(index, 1), n) - 1]
    return -1


@numba.njit(cache=True)
def _first_exit(f0, f1, lo, hi):
    """:func:`robofleet.flocking.stripe.first_exit`."""
    df = f1 - f0
    if df == 0.0:
        return 1.0
    cands = np.empty(4)
    n = 0
    for c in (lo, -lo, hi, -hi):
        if math.isfinite(c):
            s = (c - f0) / df
            if 0.0 < s < 1.0:
                cands[n] = s
                n += 1
    cands = np.sort(cands[:n])
    for q in range(n):
        nxt = cands[q + 1] if q + 1 < n else 1.0
        mid = abs(f0 + 0.5 * (cands[q] + nxt) * df)
        if mid < lo or mid > hi:
            return cands[q]
    return 1.0


@numba.njit(cache=True)
def _stable_band(mine, nearest_above, nearest_below, margin):
    """:func:`robofleet.flocking.stripe.stable_band` for the observer of key ``mine``.

    Its ranking neighbours are the smallest key ranked above it and the largest ranked
    below it in its semi-space (the band key is the primary sort key, so the neighbour
    in the full lexicographic order has it); ±inf when there is none.
    """
    upper = nearest_above - margin if nearest_above < math.inf else math.inf
    lower = nearest_below + margin if nearest_below > -math.inf else 0.0
    return min(lower, mine), max(upper, mine)


@numba.njit(cache=True)
def _compute(kind, fx, fy, lx, ly, pattern_points, pattern_axis, slots, n_slots, axis_tolerance, margin, tie_tolerance):
    """Compute (lines 1-38 and the Move) from the local snapshot (observer = row 0, others in any order).

    Returns ``(status, slot, x, y, stop)``: the local destination of a straight Move, or
    the target of a spiral Move stopped at parameter ``stop``.
    """
    m = len(fx)
    bx, by = exact_sum(fx) / m, exact_sum(fy) / m              # line 1
    tx, ty = lx - bx, ly - by                                   # line 2
    norm = math.sqrt(tx * tx + ty * ty)
    if norm <= axis_tolerance:
        return WAIT, -1, 0.0, 0.0, 1.0
    ax, ay = tx / norm, ty / norm
    lat0 = (0.0 - lx) * -ay + (0.0 - ly) * ax
    my_side = _side(lat0, axis_tolerance)
    p0 = _key(kind, 0, 0.0, 0.0, lx, ly, bx, by, ax, ay)
    tol = tie_tolerance * max(1.0, p0)                          # Sec. 6.4 "ranked equal" (p0 = dist(L, me))
    n_side = np.zeros(3, np.int64)
    n_side[my_side] += 1
    above = np.zeros(3, np.int64)                               # followers of each S_j ranked before me
    nearest_above, nearest_below = math.inf, -math.inf          # primary keys of my ranking neighbours
    tie = False
    for j in range(1, m):                                       # lines 3-5, 13: one pass, ranks counted
        x, y = fx[j], fy[j]
        sj = _side((x - lx) * -ay + (y - ly) * ax, axis_tolerance)
        n_side[sj] += 1
        pj = _key(kind, 0, x, y, lx, ly, bx, by, ax, ay)
        ahead = pj > p0 or (pj == p0 and _ranks_before(kind, x, y, lx, ly, bx, by, ax, ay))
        if ahead:
            above[sj] += 1
        if sj == my_side:
            if ahead:
                nearest_above = min(nearest_above, pj)
            else:
                nearest_below = max(nearest_below, pj)
        if kind == RANDOMIZED and sj != 0 and not tie:
            tie = _tied(pj, p0, x, y, bx, by, tol)
    lo, hi = _stable_band(p0, nearest_above, nearest_below, margin)
    k = above[my_side] + 1
    if tie and my_side != 0 and k > n_slots[my_side]:         # Sec. 6.4 case b may apply: interpreted
        return INTERPRETED, -1, 0.0, 0.0, 1.0
    slot = _choose_slot(kind, my_side, k, above, n_side, slots, n_slots)
    if slot < 0:
        return INTERPRETED, -1, 0.0, 0.0, 1.0
    c = pattern_axis[0] * ax + pattern_axis[1] * ay             # line 6: rotation B_P → L onto B → L
    s = pattern_axis[0] * ay - pattern_axis[1] * ax
    px, py = pattern_points[slot, 0], pattern_points[slot, 1]
    gx, gy = (px * c + py * -s) + lx, (px * s + py * c) + ly
    if kind == STRIPE and my_side != 0:
        u = _first_exit(lat0, (gx - lx) * -ay + (gy - ly) * ax, lo, hi)
        return SLOT, slot, u * gx, u * gy, 1.0
    if kind == HULA_HOOP:
        stop = _hoop_stop(p0, lo, hi, lx, ly, gx, gy)
        return (SLOT if stop < 0.0 else SPIRAL), slot, gx, gy, stop
    return SLOT, slot, gx, gy, 1.0


@numba.njit(cache=True)
def _choose_slot(kind, my_side, k, above, n_side, slots, n_slots):
    """Lines 15-38 (:meth:`BasicAlgorithm.choose_slot`, paper ranking); −1: a randomized coin is needed."""
    n_f0 = n_slots[0]
    if my_side == 0:                                                           # lines 31-38
        if k <= n_f0:
            return _pick(slots, n_slots, 0, k, 1)
        n1, n2 = n_side[1], n_side[2]
        if kind == RANDOMIZED:
            if n1 == n2:
                return -1                                                      # Sec. 6.4 case a: a coin
            side = 1 if n1 < n2 else 2
        else:
            side = 1 if n1 <= n2 else 2                                        # line 35
        return _pick(slots, n_slots, side, n_slots[side] - n_side[side] + (k - n_f0), side)
    s, o = my_side, 3 - my_side                                                # lines 16-30
    n_fs, n_fo, n_s0 = n_slots[s], n_slots[o], n_side[0]
    if k <= n_fs:                                                              # line 18
        return _pick(slots, n_slots, s, k, s)
    if k <= n_fs + n_f0 - n_s0:                                                # line 20
        k_prime = 1 + (k - 1 - n_fs) + max(0, above[o] - n_fo)                 # lines 21-24: Rank(me, H)
        return _pick(slots, n_slots, 0, k_prime + n_s0, s)                     # line 25
    return _pick(slots, n_slots, o, n_fo - (k - n_fs - n_f0 + n_s0) + 1, s)    # line 28


@numba.njit(cache=True)
def _hoop_stop(r0, lo, hi, lx, ly, gx, gy):
    """Sec. 5.2 (:meth:`HulaHoopAlgorithm.plan_path`): −1 for the straight Move (target in
    the annulus ``lo``–``hi``, segment clear of the inner circle), else the spiral's stop
    parameter; ``r0`` is the robot's distance from L."""
    dx, dy = gx - lx, gy - ly
    r1 = math.sqrt(dx * dx + dy * dy)
    if lo <= r1 <= hi:
        length2 = gx * gx + gy * gy                             # distance_to_segment(L, target)
        u = (lx * gx + ly * gy) / (length2 if length2 > 0 else 1.0)
        u = min(max(u, 0.0), 1.0)
        cx, cy = lx - u * gx, ly - u * gy
        return -1.0 if math.sqrt(cx * cx + cy * cy) >= lo else 1.0
    bound = hi if r1 > hi else lo
    stop = (bound - r0) / (r1 - r0) if r1 != r0 else 0.0
    return min(max(stop, 0.0), 1.0)


@numba.njit(cache=True)
def _spiral(lx, ly, gx, gy, stop, out):
    """:func:`robofleet.flocking.hula_hoop.spiral` around L from the robot (origin) towards
    (gx, gy), ``len(out)`` points."""
    ax, ay = 0.0 - lx, 0.0 - ly
    bx, by = gx - lx, gy - ly
    r0, r1 = math.sqrt(ax * ax + ay * ay), math.sqrt(bx * bx + by * by)
    th0 = math.atan2(ay, ax)
    dth = (math.atan2(by, bx) - th0 + math.pi) % (2 * math.pi) - math.pi
    points = len(out)
    step = stop / points
    for k in range(1, points + 1):
        u = k * step if k < points else stop
        r, th = r0 + u * (r1 - r0), th0 + u * dth
        out[k - 1, 0], out[k - 1, 1] = lx + r * math.cos(th), ly + r * math.sin(th)
    if stop >= 1.0:
        out[points - 1, 0], out[points - 1, 1] = gx, gy


@numba.njit(cache=True)
def _local_snapshot(wx, wy, i, mat, leader_x, leader_y, fx, fy):
    """Look of follower ``i``: the followers in its frame, M_i (p − me), into ``fx``, ``fy``
    (itself first, at the origin; the others in index order, since nothing computed from
    them depends on their order); returns the leader in its frame."""
    mx, my = wx[i], wy[i]
    fx[0], fy[0] = 0.0, 0.0
    q = 1
    for j in range(len(wx)):
        if j != i:
            dx, dy = wx[j] - mx, wy[j] - my
            fx[q], fy[q] = dx * mat[0, 0] + dy * mat[0, 1], dx * mat[1, 0] + dy * mat[1, 1]
            q += 1
    dx, dy = leader_x - mx, leader_y - my
    return dx * mat[0, 0] + dy * mat[0, 1], dx * mat[1, 0] + dy * mat[1, 1]


@numba.njit(cache=True)
def _store_move(path, cum, i, mx, my, local, n_local, mat):
    """Follower ``i``'s new world path (its position, then M_iᵀ q + me for the first
    ``n_local`` local points, the last repeated) and cumulative lengths; returns the length."""
    path[i, 0, 0], path[i, 0, 1] = mx, my
    cum[i, 0] = 0.0
    acc = 0.0
    for p in range(1, path.shape[1]):
        q = min(p, n_local) - 1
        px, py = local[q, 0], local[q, 1]
        path[i, p, 0] = (px * mat[0, 0] + py * mat[1, 0]) + mx
        path[i, p, 1] = (px * mat[0, 1] + py * mat[1, 1]) + my
        dx, dy = path[i, p, 0] - path[i, p - 1, 0], path[i, p, 1] - path[i, p - 1, 1]
        acc = acc + math.sqrt(dx * dx + dy * dy)
        cum[i, p] = acc
    return acc


@numba.njit(cache=True)
def run_events(kind, times, robots, taus, etas, leaders, path, cum, t0, travel, speed, rest, matrices,
               pattern_points, pattern_axis, slots, n_slots, axis_tolerance, margin, tie_tolerance, min_move,
               log_int, log_float, row):
    """Run the events in order from the first; stop before one that must run interpreted.

    ``log_int`` columns: robot, slot, seen_moving; ``log_float``: t_look, t_end, start x y,
    destination x y, end x y, travel, path_length; rows from ``row`` on. Returns how many
    events ran.
    """
    m = len(speed)
    wx_all, wy_all = np.empty(m), np.empty(m)
    fx, fy = np.empty(m), np.empty(m)
    points = path.shape[1] - 1
    local = np.empty((points, 2))
    for e in range(len(times)):
        t, i = times[e], robots[e]
        seen = _look_positions(path, cum, t0, travel, speed, rest, i, t, wx_all, wy_all)   # Look
        mx, my = wx_all[i], wy_all[i]
        mat = matrices[i]
        lx, ly = _local_snapshot(wx_all, wy_all, i, mat, leaders[e, 0], leaders[e, 1], fx, fy)
        status, slot, px, py, stop = _compute(kind, fx, fy, lx, ly, pattern_points, pattern_axis, slots, n_slots,
                                              axis_tolerance, margin, tie_tolerance)
        if status == INTERPRETED:
            return e
        n_local = 1
        if status == SPIRAL:
            _spiral(lx, ly, px, py, stop, local)
            n_local = points
        else:
            local[0, 0], local[0, 1] = px, py
        length = _store_move(path, cum, i, mx, my, local, n_local, mat)
        gx, gy = path[i, points, 0], path[i, points, 1]
        moved = min(length, max(min_move, etas[e] * speed[i] * taus[e]))   # A2
        t0[i], travel[i] = t, moved
        rest[i, 0], rest[i, 1] = point_at(path, cum, i, moved)
        t_end = t + taus[e]
        ex, ey = _end_position(path, cum, t0, travel, speed, i, t_end)
        log_int[row + e] = i, slot, seen
        log_float[row + e] = t, t_end, mx, my, gx, gy, ex, ey, moved, length
    return len(times)


@numba.njit(cache=True)
def _sift_down(times, robots, pos):
    """Restore the min-heap order on (Look time, robot) below ``pos``."""
    n = len(times)
    while True:
        child = 2 * pos + 1
        if child >= n:
            return
        if child + 1 < n and (times[child + 1] < times[child] or
                              (times[child + 1] == times[child] and robots[child + 1] < robots[child])):
            child += 1
        if times[child] < times[pos] or (times[child] == times[pos] and robots[child] < robots[pos]):
            times[pos], times[child] = times[child], times[pos]
            robots[pos], robots[child] = robots[child], robots[pos]
            pos = child
        else:
            return


@numba.njit(cache=True)
def heapify(times, robots):
    """Order ``times``, ``robots`` as a min-heap on (Look time, robot): the order of
    :mod:`heapq` on ``(t, i)`` tuples, so the events come out in the same sequence."""
    for pos in range(len(times) // 2 - 1, -1, -1):
        _sift_down(times, robots, pos)


@numba.njit(cache=True)
def next_events(times, robots, draws, cycle_min, cycle_max, rigidity, duration, until,
                out_t, out_robot, out_tau, out_eta):
    """The next ASYNC events from the heap of next-Look times (A1): each pops the earliest
    (t, i), draws τ ~ U(``cycle_min``, ``cycle_max``) then, for non-rigid moves,
    η ~ U(``rigidity``, 1) from ``draws`` (uniform doubles of the scheduler's stream, in
    order) and pushes (t + τ, i). Stops at the first Look at or after ``until``, after
    ``duration``, when the outputs are full or the draws run out.

    Returns ``(events, draws used)``.
    """
    rigid = rigidity >= 1.0
    need = 1 if rigid else 2
    n, used = 0, 0
    while n < len(out_t) and used + need <= len(draws) and times[0] <= duration and times[0] < until:
        t, i = times[0], robots[0]
        tau = cycle_min + (cycle_max - cycle_min) * draws[used]
        eta = 1.0 if rigid else rigidity + (1.0 - rigidity) * draws[used + 1]
        used += need
        times[0] = t + tau
        _sift_down(times, robots, 0)
        out_t[n], out_robot[n], out_tau[n], out_eta[n] = t, i, tau, eta
        n += 1
    return n, used
