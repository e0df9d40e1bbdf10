"""Flocking patterns (Def. 3.1 and Fig. 8 of Gervasi & Prencipe, TR-01-24).

A pattern ℙ is given to every follower as the coordinates of its follower points
``p_1 .. p_{n-1}`` *relative to the leader* ``p_L = (0, 0)``, with the x axis along the
leader's direction of motion (Sec. 4.2: "(0,0) represents the leader and the axes are
oriented so that x coincides with the leader's direction").

Derived quantities used by the algorithms:

* ``barycenter`` B_P of the follower points (Algorithm 1, line 7 computes it for the slots);
* ``axis``: the unit vector from B_P towards the leader. Algorithm 1 aligns it with
  the observed axis Y = B→L, so the pattern's *estimated heading* is ``axis``;
* ``lateral``: signed distance of every point to the line through L and B_P, positive on
  the left of ``axis`` (counter-clockwise side);
* lb-symmetry (Sec. 4.1, item 2): the pattern is symmetric w.r.t. the line through L and B_P;
* the radius R_P (Def. 3.1): ``max_i dist(p_L, p_i)``.

The coordinates of Fig. 8 are not printed in the paper; the fixed patterns below are our
reconstruction with the stated number of followers and scale of the random patterns
(box (−150, −50)–(−50, 50)): all lb-symmetric, at most one point on the axis.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np
import yaml

from ..core.budget import check_allocation
from ..core.errors import ScenarioError
from ..core.rng import RngLike, as_generator

#: Relative tolerance for geometric equalities on pattern points (scaled by max(1, R_P)).
PATTERN_TOLERANCE = 1e-9
PAIR_BYTES = 24  # the pairwise gaps validate_points computes, per pair of points (memory budget)

PatternKind = Literal["wedge", "line", "spread", "random", "points", "file"]


@dataclass(frozen=True)
class Pattern:
    """A validated pattern: follower points relative to the leader, heading along +x.

    Use :func:`validate_points` (or :func:`make_pattern`) to build one from user input.

    Parameters
    ----------
    points:
        ``(m, 2)`` float64 follower points ``p_1 .. p_m`` (the leader is the origin).
    name:
        Label used in tables and plots.
    """

    points: np.ndarray
    name: str = "pattern"
    tolerance: float = field(default=PATTERN_TOLERANCE, repr=False)

    @property
    def size(self) -> int:
        """Number of follower slots ``|ℙ| − 1``."""
        return int(len(self.points))

    @cached_property
    def barycenter(self) -> np.ndarray:
        """B_P, the barycenter of the follower points."""
        return self.points.mean(axis=0)

    @cached_property
    def axis(self) -> np.ndarray:
        """Unit vector B_P → L: the heading Algorithm 1 assumes for the pattern."""
        return -self.barycenter / np.linalg.norm(self.barycenter)

    @cached_property
    def radius(self) -> float:
        """R_P = max_i dist(p_L, p_i) (Def. 3.1)."""
        return float(np.linalg.norm(self.points, axis=1).max())

    @property
    def scale_tolerance(self) -> float:
        """Absolute tolerance ``tolerance · max(1, R_P)``."""
        return self.tolerance * max(1.0, self.radius)

    @cached_property
    def lateral(self) -> np.ndarray:
        """Signed distance of each point to the line L–B_P, positive left of :attr:`axis`."""
        a = self.axis
        return a[0] * self.points[:, 1] - a[1] * self.points[:, 0]

    @cached_property
    def side(self) -> np.ndarray:
        """``+1`` left of the axis (F_1), ``-1`` right (F_2), ``0`` on it (F_0)."""
        lat = self.lateral
        return np.where(np.abs(lat) <= self.scale_tolerance, 0, np.sign(lat)).astype(int)

    @property
    def n_on_axis(self) -> int:
        """Number of points on the line through L and B_P (``|F_0|``)."""
        return int(np.count_nonzero(self.side == 0))

    def mirrored(self) -> np.ndarray:
        """The points reflected across the line L–B_P."""
        n = np.array([-self.axis[1], self.axis[0]])
        return self.points - 2.0 * self.lateral[:, None] * n

    @cached_property
    def is_lb_symmetric(self) -> bool:
        """Sec. 4.1 item 2: symmetric w.r.t. the axis through L and B_P."""
        gap = np.linalg.norm(self.mirrored()[:, None, :] - self.points[None, :, :], axis=-1)
        return bool(np.all(gap.min(axis=1) <= 10 * self.scale_tolerance))

    @property
    def is_directed(self) -> bool:
        """True when B_P lies on the negative x axis, so estimated and real heading agree."""
        return bool(np.allclose(self.axis, [1.0, 0.0], atol=1e-9))

    def axis_slot_ranked_ahead(self) -> np.ndarray:
        """Off-axis points that Algorithm 1's ranking does not place ahead of the single
        on-axis point (empty when there is no axis point, or it ranks behind them all).

        Lines 12-13 sort slots and followers by decreasing distance from L, and lines
        18-25 send a follower of S_s to the on-axis slot only when it ranks beyond
        ``|F_s|`` — behind every follower holding a slot of its side. A follower that
        approaches the on-axis slot stays in S_s until it is within the axis tolerance,
        ranked by its own distance from L, about that of the slot: if the slot is not
        strictly nearer to L than every off-axis slot, the follower is ranked among the
        side slots and sent to one of them, another follower is sent to the axis slot,
        and the two swap for ever (e.g. a diamond whose axis point is the farthest).
        Distances within :attr:`scale_tolerance` count as a tie (an ambiguous ranking).
        """
        if self.n_on_axis != 1:
            return np.empty(0, dtype=np.intp)
        distance = np.linalg.norm(self.points, axis=1)
        axis_distance = float(distance[self.side == 0][0])
        return np.flatnonzero((self.side != 0) & (distance <= axis_distance + self.scale_tolerance))

    def supported_by_basic(self) -> tuple[bool, str]:
        """Whether Algorithm 1 (and its Sec. 5 variants) can form this pattern.

        Sec. 4.1 and Sec. 6.2.1: the pattern must be lb-symmetric and have at most one
        point on the L–B_P axis. Returns ``(ok, reason)``.
        """
        if not self.is_lb_symmetric:
            return False, "an lb-symmetric pattern (symmetric about the line through the leader and the followers' barycenter)"
        if self.n_on_axis > 1:
            return False, f"at most 1 point on the leader-barycenter axis (pattern has {self.n_on_axis})"
        return True, ""


def validate_points(points: np.ndarray | Sequence[Sequence[float]], *, name: str = "pattern", field: str = "pattern.points",
                    source: str | None = None) -> Pattern:
    """Build a :class:`Pattern` from user input, raising :class:`ScenarioError` on bad input.

    Checks: a finite ``(m, 2)`` array with ``m ≥ 1``; no point on the leader; no two
    equal points (the paper assumes distinct slots); the barycenter differs from the
    leader (otherwise the axis L–B_P of Algorithm 1 is undefined).
    """
    try:
        arr = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise ScenarioError(field, "a list of [x, y] points", points, source=source) from None
    if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < 1:
        raise ScenarioError(field, "a non-empty list of [x, y] points", f"shape {arr.shape}", source=source)
    if not np.all(np.isfinite(arr)):
        raise ScenarioError(field, "finite coordinates", points, source=source)
    check_allocation(PAIR_BYTES * len(arr) ** 2, f"pattern of {len(arr)} points", field, source)  # input validation
    tol = PATTERN_TOLERANCE * max(1.0, float(np.abs(arr).max()))
    gap = np.linalg.norm(arr[:, None] - arr[None], axis=-1)
    np.fill_diagonal(gap, np.inf)
    if np.any(gap <= tol):
        i, j = np.argwhere(gap <= tol)[0]
        raise ScenarioError(field, "distinct points (no duplicates)", f"point {i} == point {j} == {arr[i].tolist()}", source=source)
    if np.any(np.linalg.norm(arr, axis=1) <= tol):
        raise ScenarioError(field, "no point on the leader position (0, 0)", points, source=source)
    if np.linalg.norm(arr.mean(axis=0)) <= tol:
        raise ScenarioError(field, "a barycenter of the follower points away from the leader (0, 0)", arr.mean(axis=0).tolist(), source=source)
    return Pattern(arr, name)


def wedge() -> Pattern:
    """Wedge of six followers (Fig. 8, reconstructed): a V opening behind the leader."""
    k = np.arange(1, 4, dtype=float)
    pts = np.concatenate([np.column_stack([-40 * k, 40 * k]), np.column_stack([-40 * k, -40 * k])])
    return Pattern(pts, "wedge")


def line() -> Pattern:
    """Line of four followers abreast behind the leader (Fig. 8, reconstructed)."""
    pts = np.array([[-60.0, 30.0], [-60.0, -30.0], [-60.0, 90.0], [-60.0, -90.0]])
    return Pattern(pts, "line")


def spread() -> Pattern:
    """Spread formation of ten followers (Fig. 8, reconstructed): five symmetric pairs."""
    half = np.array([[-50.0, 30.0], [-50.0, 90.0], [-100.0, 60.0], [-100.0, 120.0], [-150.0, 30.0]])
    return Pattern(np.concatenate([half, half * [1.0, -1.0]]), "spread")


def random_lb_symmetric(n_points: int | None = None, rng: RngLike = None, low: Sequence[float] = (-150.0, -50.0),
                        high: Sequence[float] = (-50.0, 50.0)) -> Pattern:
    """A random lb-symmetric pattern as in Sec. 4.2.

    ``n_points`` (2..8 in the paper; drawn uniformly from 2..8 when ``None``) points in
    the box ``low``–``high``, symmetric about the x axis: ``n // 2`` mirrored pairs
    ``(x, ±y)`` with ``y > 0``, plus one point ``(x, 0)`` on the axis when ``n`` is odd.
    """
    gen = as_generator(rng)
    if n_points is not None and (isinstance(n_points, (bool, np.bool_)) or not isinstance(n_points, (int, np.integer))):
        raise ScenarioError("pattern.n_points", "an integer >= 1", n_points)
    n = int(gen.integers(2, 9)) if n_points is None else int(n_points)
    if n < 1:
        raise ScenarioError("pattern.n_points", "an integer >= 1", n_points)
    check_allocation(PAIR_BYTES * n**2, f"pattern of {n} points", "pattern.n_points")  # input validation
    pairs = n // 2
    x = gen.uniform(low[0], high[0], size=pairs + n % 2)
    y = gen.uniform(0.0, high[1], size=pairs)
    y = np.maximum(y, 1e-3 * (high[1] - low[1]))  # keep pairs off the axis
    pts = [np.column_stack([x[:pairs], y]), np.column_stack([x[:pairs], -y])]
    if n % 2:
        pts.append([[x[-1], 0.0]])
    return validate_points(np.concatenate(pts), name=f"random{n}")


def from_file(path: str | Path, *, field: str = "pattern.path", source: str | None = None) -> Pattern:
    """Read a pattern file: YAML ``points: [[x, y], ...]`` or a two-column CSV/whitespace file."""
    p = Path(path)
    if source and not p.is_absolute():
        p = Path(source).parent / p
    try:
        text = p.read_text()
    except OSError as exc:
        raise ScenarioError(field, "a readable pattern file", f"{p} ({exc.strerror})", source=source) from None
    if p.suffix.lower() in (".yaml", ".yml", ".json"):
        doc = yaml.safe_load(text)
        pts = doc.get("points") if isinstance(doc, dict) else doc
    else:
        try:
            pts = np.loadtxt(p, delimiter="," if p.suffix.lower() == ".csv" else None, ndmin=2)
        except ValueError as exc:
            raise ScenarioError(field, "two numeric columns x, y", str(exc), source=str(p)) from None
    return validate_points(pts, name=p.stem, field="points", source=str(p))


BUILTIN = {"wedge": wedge, "line": line, "spread": spread}


def make_pattern(kind: str, *, points: np.ndarray | Sequence[Sequence[float]] | None = None, n_points: int | None = None,
                 path: str | Path | None = None, rng: RngLike = None, source: str | None = None) -> Pattern:
    """Pattern factory used by scenario files (``pattern.kind``)."""
    if kind in BUILTIN:
        return BUILTIN[kind]()
    if kind == "random":
        return random_lb_symmetric(n_points, rng)
    if kind == "points":
        return validate_points(points, source=source)
    if kind == "file":
        return from_file(path, source=source)
    raise ScenarioError("pattern.kind", f"one of {sorted([*BUILTIN, 'random', 'points', 'file'])}", kind, source=source)
