"""Spec blocks every family's scenario shares: one workspace vocabulary.

A ``workspace:`` block reads the same in every family::

    workspace:
      bounds: [xmin, ymin, xmax, ymax]     # or a polygon [[x, y], ...]
      corner_radius: 0                     # rounds a rectangle's corners
      obstacles:                           # each a box or a polygon
        - {center: [1, 2], size: [1, 1], yaw: 0.3}
        - {vertices: [[0, 0], [1, 0], [0, 1]]}
        - [[0, 0], [1, 0], [0, 1]]         # a bare polygon, short for {vertices: ...}
      regions:
        - {name: crossing, vertices: [[...]], ...}

A scenario that derives from :class:`RecordingSpec` takes ``record_every: k`` (default 1):
its run keeps the states and per-step arrays of steps 0, k, 2k, … only, while the run
itself, and every per-run result, still see every step (see
:class:`~robofleet.core.recorder.Recorder`).

Families subclass :class:`WorkspaceSpec` to add what only they need (the uncertainty of
obstacle positions in avoidance, a preset map in coordination, a region's disturbance
probability) and to tighten it (convex shapes for B-UAVC cells, non-overlapping
obstacles for the grid search); the vocabulary itself stays one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Optional, Union

import numpy as np
from pydantic import Field, field_validator, model_validator
from shapely.geometry import Polygon

from . import geometry
from .config import SpecModel
from .errors import ScenarioError
from .workspace import Region, Workspace

Point = tuple[float, float]
ARC_STEP_DEGREES = 5.0


def finite_points(value: Any, field: str = "") -> np.ndarray:
    """``value`` as a finite ``(k, 2)`` float array, or a one-line :class:`ScenarioError`."""
    try:
        pts = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ScenarioError(field, "a list of [x, y] points", value) from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ScenarioError(field, "a list of [x, y] points", value)
    if not np.all(np.isfinite(pts)) or np.abs(pts).max(initial=0.0) > 1e12:
        raise ScenarioError(field, "finite coordinates (|x| ≤ 1e12)", value)
    return pts


def simple_polygon(value: Any, field: str = "", what: str = "polygon") -> np.ndarray:
    """Counter-clockwise vertices of a simple polygon with positive area."""
    pts = finite_points(value, field)
    poly = Polygon(pts) if len(pts) >= 3 else None
    if poly is None or not poly.is_valid or poly.area <= 0:
        raise ScenarioError(field, f"a simple {what} of at least 3 vertices with positive area", value)
    return geometry.ensure_ccw(pts)


def is_convex(vertices: np.ndarray) -> bool:
    """Whether the simple polygon ``vertices`` is convex."""
    poly = Polygon(vertices)
    return bool(np.isclose(poly.convex_hull.area, poly.area))


def rounded_rectangle(rectangle: Sequence[float], radius: float, step_degrees: float = ARC_STEP_DEGREES) -> np.ndarray:
    """Counter-clockwise vertices of a rectangle whose corners are arcs of ``radius``."""
    x0, y0, x1, y1 = rectangle
    centres = [(x1 - radius, y0 + radius, -90.0), (x1 - radius, y1 - radius, 0.0),
               (x0 + radius, y1 - radius, 90.0), (x0 + radius, y0 + radius, 180.0)]
    angles = np.deg2rad(np.arange(0.0, 90.0 + 1e-9, step_degrees))
    arcs = [np.column_stack([cx + radius * np.cos(np.deg2rad(a0) + angles), cy + radius * np.sin(np.deg2rad(a0) + angles)])
            for cx, cy, a0 in centres]
    return np.concatenate(arcs)


class RecordingSpec(SpecModel):
    """What a run records: ``record_every`` k keeps the states and per-step arrays of
    steps 0, k, 2k, … (the trajectory and every per-run result are those of every step)."""

    record_every: int = Field(1, ge=1)

    @field_validator("record_every", mode="before")
    @classmethod
    def _not_a_flag(cls, value):  # input validation: pydantic would read true as 1
        if isinstance(value, bool):
            raise ScenarioError("", "a positive integer (record every k-th step)", value)
        return value


class ObstacleSpec(SpecModel):
    """A static polygonal obstacle: a box (``center``, ``size``, ``yaw``) or ``vertices``.

    A bare list of points is read as ``{vertices: ...}``.
    """

    center: Optional[Point] = None
    size: Optional[tuple[float, float]] = None
    yaw: float = 0.0
    vertices: Optional[list[Point]] = None

    @model_validator(mode="before")
    @classmethod
    def _bare_polygon(cls, data):
        return {"vertices": data} if isinstance(data, (list, tuple)) else data

    @model_validator(mode="after")
    def _shape(self):
        if (self.vertices is None) == (self.center is None):
            raise ScenarioError("", "either 'center' and 'size' (a box) or 'vertices'", self.model_dump(exclude_none=True))
        if self.center is not None:
            finite_points([self.center], "center")
            if self.size is None or not all(math.isfinite(s) and 0 < s <= 1e12 for s in self.size):
                raise ScenarioError("size", "two positive finite numbers", self.size)
            if not math.isfinite(self.yaw):
                raise ScenarioError("yaw", "a finite angle in radians", self.yaw)
        else:
            simple_polygon(self.vertices, "vertices")
        return self

    def polygon(self) -> np.ndarray:
        """Counter-clockwise vertices ``(k, 2)``."""
        if self.vertices is not None:
            return geometry.ensure_ccw(np.asarray(self.vertices, float))
        return geometry.box_vertices(self.center, self.size, self.yaw)


class RegionSpec(SpecModel):
    """A named polygonal region; families subclass it to add the region's attributes."""

    name: str
    vertices: list[Point]

    @field_validator("vertices")
    @classmethod
    def _polygon(cls, value):
        simple_polygon(value, "", "region polygon")
        return value

    def attributes(self) -> dict[str, Any]:
        """The fields beyond ``name`` and ``vertices`` (the :class:`Region` attributes)."""
        return self.model_dump(exclude={"name", "vertices"})

    def build(self) -> Region:
        return Region(self.name, np.asarray(self.vertices, float), self.attributes())


class WorkspaceSpec(SpecModel):
    """Bounds (a rectangle, optionally with rounded corners, or a polygon), obstacles and
    regions: the one workspace vocabulary of every family (see the module docstring)."""

    bounds: Union[tuple[float, float, float, float], list[Point]] = (-5.0, -5.0, 5.0, 5.0)
    corner_radius: float = Field(0.0, ge=0.0)
    obstacles: list[ObstacleSpec] = Field(default_factory=list)
    regions: list[RegionSpec] = Field(default_factory=list)

    @model_validator(mode="before")
    @classmethod
    def _rectangle_alias(cls, data):
        """``rectangle: [xmin, ymin, xmax, ymax]`` (the search family's earlier key) is ``bounds``."""
        if isinstance(data, dict) and "rectangle" in data:
            data = dict(data)
            if "bounds" in data:
                raise ScenarioError("rectangle", "either bounds or rectangle (the same thing), not both", data["rectangle"])
            data["bounds"] = data.pop("rectangle")
        return data

    @model_validator(mode="after")
    def _geometry(self):
        if self.is_rectangle:
            x0, y0, x1, y1 = self.bounds
            if not all(math.isfinite(v) and abs(v) <= 1e12 for v in self.bounds) or not (x0 < x1 and y0 < y1):
                raise ScenarioError("bounds", "finite [xmin, ymin, xmax, ymax] with min < max", list(self.bounds))
            if 2 * self.corner_radius >= min(x1 - x0, y1 - y0):
                raise ScenarioError("corner_radius", f"a radius below half the rectangle's shorter side ({min(x1 - x0, y1 - y0) / 2:g})", self.corner_radius)
        else:
            simple_polygon(self.bounds, "bounds", "bounds polygon")
            if self.corner_radius:
                raise ScenarioError("corner_radius", "0 unless the bounds are a rectangle [xmin, ymin, xmax, ymax]", self.corner_radius)
        return self

    @property
    def is_rectangle(self) -> bool:
        """Whether ``bounds`` is given as ``[xmin, ymin, xmax, ymax]``."""
        return len(self.bounds) == 4 and not isinstance(self.bounds[0], (list, tuple))

    def bounds_vertices(self) -> np.ndarray:
        """Counter-clockwise vertices of the bounds (arcs sampled every 5° where rounded)."""
        if self.is_rectangle:
            if self.corner_radius:
                return rounded_rectangle(self.bounds, self.corner_radius)
            x0, y0, x1, y1 = self.bounds
            return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)
        return geometry.ensure_ccw(np.asarray(self.bounds, float))

    def obstacle_polygons(self) -> list[np.ndarray]:
        return [o.polygon() for o in self.obstacles]

    def build(self) -> Workspace:
        """The :class:`~robofleet.core.workspace.Workspace` this block describes."""
        return Workspace(self.bounds_vertices(), tuple(self.obstacle_polygons()), tuple(r.build() for r in self.regions))
