"""The start and goal check of a coordination scenario (:func:`check_endpoints`), used by the
scenario model (:mod:`robofleet.coordination.spec`) and the planner (:mod:`robofleet.coordination.planner`)."""

from __future__ import annotations

import numpy as np

from ..core.errors import ScenarioError
from ..core.workspace import Workspace


def check_endpoints(workspace: Workspace, starts: np.ndarray, goals: np.ndarray, radius: float) -> None:
    """Starts and goals must have clearance ``≥ r`` and be ``≥ 2r`` apart (ScenarioError otherwise)."""
    for name, pts in (("starts", starts), ("goals", goals)):
        clearance = workspace.clearance(pts)
        bad = np.flatnonzero(clearance < radius)
        if len(bad):
            raise ScenarioError(f"robots.{name}[{bad[0]}]", f"a point inside the free space with clearance >= radius {radius}",
                                pts[bad[0]].round(2).tolist())
        d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(len(pts)) * 1e18
        i, j = np.unravel_index(np.argmin(d), d.shape)
        if len(pts) > 1 and d[i, j] < 2 * radius:
            raise ScenarioError(f"robots.{name}[{max(i, j)}]", f"at least 2r = {2 * radius} from robots.{name}[{min(i, j)}]",
                                pts[max(i, j)].round(2).tolist())
