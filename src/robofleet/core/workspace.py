"""The workspace: bounds, static polygonal obstacles and named regions.

Shapely polygons are kept for exact set operations (validation, plotting, roadmaps);
the vertex arrays are what the vectorized kernels of :mod:`robofleet.core.geometry` use
in hot paths.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
import shapely
from shapely.geometry import Polygon, box
from shapely.geometry.base import BaseGeometry

from . import geometry
from .errors import ConfigError, short_repr


DISTANCE_BLOCK = 1 << 18
"""Point–edge pairs :meth:`Workspace.obstacle_distance` computes at once (several obstacles
per block for few points, one obstacle at a time for very many)."""


def polygon_vertices(value: Any, name: str) -> np.ndarray:
    """``value`` as finite float vertices ``(k, 2)``, ``k ≥ 3``, or a one-line :class:`ConfigError`."""
    try:
        vertices = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        vertices = None
    if vertices is None or vertices.ndim != 2 or vertices.shape[1] != 2 or len(vertices) < 3:
        raise ConfigError(f"{name}: expected polygon vertices shaped (k, 2) with k ≥ 3, received {short_repr(value)}")
    if not np.all(np.isfinite(vertices)):
        raise ConfigError(f"{name}: expected finite coordinates, received {short_repr(value)}")
    return vertices


@dataclass(frozen=True)
class Region:
    """A named polygonal region with free-form attributes (e.g. ``probability: 0.85``)."""

    name: str
    vertices: np.ndarray
    attributes: Mapping[str, Any] = field(default_factory=dict)

    @property
    def polygon(self) -> Polygon:
        return Polygon(self.vertices)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Boolean mask: points inside (or on the boundary of) the region."""
        pts = np.asarray(points, dtype=float)
        return shapely.intersects_xy(self.polygon, pts[..., 0], pts[..., 1])


@dataclass(frozen=True)
class Workspace:
    """A 2D workspace.

    Parameters
    ----------
    bounds:
        Vertices ``(V, 2)`` of the outer boundary (a rectangle or any simple polygon).
    obstacles:
        Tuple of vertex arrays ``(V_k, 2)``, one per static polygonal obstacle,
        stored counter-clockwise.
    regions:
        Named regions with attributes.
    """

    bounds: np.ndarray
    obstacles: tuple[np.ndarray, ...] = ()
    regions: tuple[Region, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "bounds", polygon_vertices(self.bounds, "bounds"))
        if isinstance(self.obstacles, np.ndarray) or not isinstance(self.obstacles, Iterable):
            raise ConfigError(f"obstacles: expected a sequence of (k, 2) vertex arrays, received {short_repr(self.obstacles)}")
        object.__setattr__(self, "obstacles", tuple(polygon_vertices(o, f"obstacles[{k}]") for k, o in enumerate(self.obstacles)))
        regions = tuple(self.regions) if isinstance(self.regions, Iterable) else None
        if regions is None or not all(isinstance(r, Region) for r in regions):
            raise ConfigError(f"regions: expected a sequence of Region, received {short_repr(self.regions)}")
        object.__setattr__(self, "regions", regions)

    @classmethod
    def rectangle(cls, xmin: float, ymin: float, xmax: float, ymax: float, obstacles: Iterable[np.ndarray] = (), regions: Iterable[Region] = ()) -> "Workspace":
        """A rectangular workspace ``[xmin, xmax] × [ymin, ymax]``."""
        bounds = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]], dtype=float)
        return cls(bounds, tuple(geometry.ensure_ccw(o) for o in obstacles), tuple(regions))

    @property
    def boundary_polygon(self) -> Polygon:
        return Polygon(self.bounds)

    @property
    def obstacle_polygons(self) -> list[Polygon]:
        return [Polygon(o) for o in self.obstacles]

    @property
    def free_polygon(self) -> BaseGeometry:
        """The free space ``bounds \\ ∪ obstacles`` as a shapely geometry."""
        return self.boundary_polygon.difference(shapely.union_all(self.obstacle_polygons)) if self.obstacles else self.boundary_polygon

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the bounds."""
        lo, hi = self.bounds.min(axis=0), self.bounds.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    @property
    def is_rectangle(self) -> bool:
        return self.boundary_polygon.equals(box(*self.extent))

    def region(self, name: str) -> Region:
        for r in self.regions:
            if r.name == name:
                return r
        raise KeyError(name)

    def obstacle_distance(self, points: np.ndarray) -> np.ndarray:
        """Distance from each point to the nearest obstacle (0 inside one, ``inf`` if none):
        :func:`~.geometry.polygon_distance` of every obstacle, the obstacles taken together
        in blocks of at most :data:`DISTANCE_BLOCK` point–edge pairs (the same numbers)."""
        pts = np.asarray(points, dtype=float)
        out = np.full(pts.shape[:-1], np.inf)
        edges = self._obstacle_edges
        count = max(1, int(np.prod(out.shape)))
        lo = 0
        while lo < len(self.obstacles):
            hi = lo + 1  # at least one obstacle, else as many as the block holds
            while hi < len(self.obstacles) and edges.offsets[hi + 1] - edges.offsets[lo] <= DISTANCE_BLOCK // count:
                hi += 1
            out = np.minimum(out, edges.distance(pts, lo, hi))
            lo = hi
        return out

    @functools.cached_property
    def _obstacle_edges(self) -> geometry.PolygonEdges:
        return geometry.PolygonEdges(self.obstacles)

    def boundary_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance to the outer boundary: positive inside, negative outside."""
        pts = np.asarray(points, dtype=float)
        start, end = geometry.polygon_edges(self.bounds)
        d = geometry.point_segment_distance(pts, start, end).min(axis=-1)
        inside = geometry.points_in_polygon(pts, self.bounds)
        return np.where(inside, d, -d)

    def clearance(self, points: np.ndarray) -> np.ndarray:
        """Distance to the nearest obstacle or boundary (negative outside the bounds)."""
        return np.minimum(self.obstacle_distance(points), self.boundary_distance(points))

    def free_area(self) -> float:
        return float(self.free_polygon.area)
