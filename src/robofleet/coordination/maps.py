"""The X-plus-corridor map of the label-flipping deadlock paper (2021)'s experiment (Fig. 1) and its three flows.

The exact polygon is not published; this one has the published dimensions (3000 × 2400,
length unit ≈ 2 cm) and makes the three flows cross:

* arm A, the band ``0 ≤ x − y ≤ 400`` from the bottom-left to the top-right corner;
* arm B, the band ``2600 ≤ x + y ≤ 3000`` from the top-left corner down to ``y = 650``,
  whose top part is the disturbance region ``(650, 1950), (1050, 1950), (600, 2400),
  (200, 2400)``;
* a horizontal corridor ``1600 ≤ y ≤ 2000`` across the whole width;
* four rooms holding the flows' start and goal boxes.

Flows, by robot index mod 5 (facts from the authors' release):

==============  ===========================  ==========================
index mod 5     start box (x, y ranges)      goal box
==============  ===========================  ==========================
1, 2            (50, 700) × (50, 300)        (1950, 2800) × (1950, 2350)
0               (200, 750) × (2250, 2350)    (1550, 2350) × (650, 1050)
3, 4            (2500, 3000) × (1650, 1950)  (50, 650) × (1650, 1950)
==============  ===========================  ==========================
"""

from __future__ import annotations

import functools
from collections.abc import Iterable

import numpy as np
import shapely
from shapely.geometry import Polygon, box

from ..core.errors import InfeasibleError
from ..core.geometry import ensure_ccw
from ..core.workspace import Region, Workspace

DISTURBANCE_REGION = np.array([[650.0, 1950.0], [1050.0, 1950.0], [600.0, 2400.0], [200.0, 2400.0]])

# (start box, goal box) per flow; boxes are (xmin, xmax, ymin, ymax)
FLOWS = {
    "south_west_to_north_east": ((50, 700, 50, 300), (1950, 2800, 1950, 2350)),
    "north_west_to_south_east": ((200, 750, 2250, 2350), (1550, 2350, 650, 1050)),
    "east_to_west": ((2500, 3000, 1650, 1950), (50, 650, 1650, 1950)),
}


def flow_of(robot: np.ndarray | int) -> np.ndarray:
    """Flow name of each robot index (index mod 5: 1, 2 → SW→NE; 0 → NW→SE; 3, 4 → E→W)."""
    table = np.array(["north_west_to_south_east", "south_west_to_north_east", "south_west_to_north_east", "east_to_west", "east_to_west"])
    return table[np.asarray(robot) % 5]


@functools.lru_cache(maxsize=1)
def x_corridor_free_space() -> shapely.Geometry:
    """The free space of the map as a shapely polygon (with holes); built once per process
    (shapely geometries are immutable)."""
    arm_a = Polygon([(0, 0), (400, 0), (2800, 2400), (2400, 2400)])
    arm_b = Polygon([(200, 2400), (600, 2400), (2350, 650), (1950, 650)])
    corridor = box(0, 1600, 3000, 2000)
    rooms = [box(0, 0, 750, 350), box(1900, 1900, 2850, 2400), box(150, 2200, 800, 2400), box(1500, 600, 2400, 1100)]
    return shapely.union_all([arm_a, arm_b, corridor, *rooms]).intersection(box(0, 0, 3000, 2400))


def x_corridor_workspace(region_probability: float = 0.85) -> Workspace:
    """The map as a :class:`Workspace`: outer boundary, holes as obstacles, the disturbance region."""
    return workspace_from_free_space(
        x_corridor_free_space(),
        regions=(Region("disturbance", DISTURBANCE_REGION.copy(), {"probability": float(region_probability)}),),
    )


def workspace_from_free_space(free: Polygon, regions: Iterable[Region] = ()) -> Workspace:
    """A workspace whose bounds are the free polygon's exterior and whose obstacles are its holes."""
    exterior = np.asarray(free.exterior.coords, dtype=float)[:-1]
    holes = tuple(np.asarray(h.coords, dtype=float)[:-1] for h in free.interiors)
    return Workspace(ensure_ccw(exterior), tuple(ensure_ccw(h) for h in holes), tuple(regions))


def free_space(workspace: Workspace) -> shapely.Geometry:
    """Free space of any workspace (bounds minus obstacles)."""
    return workspace.free_polygon


def probability_map(workspace: Workspace, points: np.ndarray, base_probability: float) -> np.ndarray:
    """Disturbance probability at ``points`` ``(..., 2)``: the last region containing the point
    that has a ``probability`` attribute, else ``base_probability``."""
    pts = np.asarray(points, dtype=float)
    p = np.full(pts.shape[:-1], float(base_probability))
    for region in workspace.regions:
        if "probability" in region.attributes:
            p = np.where(region.contains(pts), float(region.attributes["probability"]), p)
    return p


def sample_flow_instance(workspace: Workspace, n_robots: int, radius: float, rng: np.random.Generator,
                         separation: float = 4.0, max_tries: int = 20000) -> tuple[np.ndarray, np.ndarray]:
    """Random starts and goals in the flows' boxes (robot ``i`` in flow ``i mod 5``).

    Points keep clearance ``r`` from the walls and ``separation · r`` from the other
    starts (goals), so that discs around them never close a passage (valid infrastructure).
    """
    free = shapely.buffer(workspace.free_polygon, -radius * 1.01)
    shapely.prepare(free)
    flows = flow_of(np.arange(n_robots))
    starts, goals = np.empty((n_robots, 2)), np.empty((n_robots, 2))
    for kind, out in ((0, starts), (1, goals)):
        for i in range(n_robots):
            x0, x1, y0, y1 = FLOWS[flows[i]][kind]
            for _ in range(max_tries):
                p = rng.uniform([x0, y0], [x1, y1])
                if shapely.contains_xy(free, p[0], p[1]) and np.all(np.linalg.norm(out[:i] - p, axis=1) >= separation * radius):
                    out[i] = p
                    break
            else:
                raise InfeasibleError(f"robots: expected room for {n_robots} robots in the flow boxes, received none for robot {i}")
    return starts, goals


# -- a warehouse of shelves (the grid instances of ``robofleet reproduce coordination-peers``) --------------
WAREHOUSE_COLUMNS, WAREHOUSE_ROWS = 8, 7
WAREHOUSE_SHELF = (375.0, 150.0)
WAREHOUSE_AISLE = 225.0
WAREHOUSE_MARGIN = 225.0
STATION_GAP = 30.0
"""Distance of a station's centre from its shelf's face."""
STATION_PITCH = 75.0
WAREHOUSE_DISTURBANCE = np.array([[2200.0, 1150.0], [2800.0, 1150.0], [2800.0, 1650.0], [2200.0, 1650.0]])
"""The warehouse's disturbance region: a patch of floor in the middle, where the east-west traffic crosses."""


def warehouse_extent() -> tuple[float, float]:
    """Width and height of the warehouse (5025 × 2850 with the constants above)."""
    width = 2 * WAREHOUSE_MARGIN + WAREHOUSE_COLUMNS * WAREHOUSE_SHELF[0] + (WAREHOUSE_COLUMNS - 1) * WAREHOUSE_AISLE
    height = 2 * WAREHOUSE_MARGIN + WAREHOUSE_ROWS * WAREHOUSE_SHELF[1] + (WAREHOUSE_ROWS - 1) * WAREHOUSE_AISLE
    return width, height


def warehouse_shelf_corners() -> np.ndarray:
    """Lower-left corners ``(columns · rows, 2)`` of the shelves, column by column."""
    c, r = np.meshgrid(np.arange(WAREHOUSE_COLUMNS), np.arange(WAREHOUSE_ROWS), indexing="ij")
    x = WAREHOUSE_MARGIN + c.ravel() * (WAREHOUSE_SHELF[0] + WAREHOUSE_AISLE)
    y = WAREHOUSE_MARGIN + r.ravel() * (WAREHOUSE_SHELF[1] + WAREHOUSE_AISLE)
    return np.column_stack([x, y])


def warehouse_workspace(region_probability: float = 0.85) -> Workspace:
    """A warehouse-like grid map: ``8 × 7`` shelves of ``375 × 150`` with aisles of ``225``
    (room for two robots of radius 15 to pass a robot parked at a shelf) in a rectangle,
    and a disturbance region in the middle (:data:`WAREHOUSE_DISTURBANCE`)."""
    width, height = warehouse_extent()
    w, h = WAREHOUSE_SHELF
    shelves = tuple(np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]]) for x, y in warehouse_shelf_corners())
    region = Region("disturbance", WAREHOUSE_DISTURBANCE.copy(), {"probability": float(region_probability)})
    return Workspace.rectangle(0.0, 0.0, width, height, shelves, (region,))


def warehouse_stations() -> np.ndarray:
    """Pick stations ``(k, 2)``: along both long faces of every shelf, ``STATION_PITCH``
    apart and ``STATION_GAP`` from the face (4 per face, 448 in all), leaving the middle
    of each aisle free."""
    offsets = np.arange(STATION_PITCH, WAREHOUSE_SHELF[0] - 1.0, STATION_PITCH)
    corners = warehouse_shelf_corners()
    below = np.stack([corners[:, None, 0] + offsets[None], np.repeat(corners[:, 1:2] - STATION_GAP, len(offsets), axis=1)], -1)
    above = below + np.array([0.0, WAREHOUSE_SHELF[1] + 2 * STATION_GAP])
    return np.concatenate([below.reshape(-1, 2), above.reshape(-1, 2)])


def sample_station_instance(n_robots: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Starts and goals at ``2 n`` distinct random stations of the warehouse (:func:`warehouse_stations`)."""
    stations = warehouse_stations()
    if 2 * n_robots > len(stations):
        raise InfeasibleError(f"robots.count: expected at most {len(stations) // 2} robots (two stations each), received {n_robots}")
    pick = rng.choice(len(stations), 2 * n_robots, replace=False)
    return stations[pick[:n_robots]].copy(), stations[pick[n_robots:]].copy()
