"""Scenario files of the rendezvous family: the validated ``Spec``.

Example::

    family: rendezvous
    robots: {n: 20, area: 10.0, sensing_range: 3.0, gain: 0.5}
    tolerance: 0.05
    max_steps: 300
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from robofleet.core.budget import RunSize
from robofleet.core.config import SpecModel


class RobotsSpec(SpecModel):
    """How many robots, where they start and what they sense."""

    n: int = Field(20, ge=1, le=100_000)
    area: float = Field(10.0, gt=0, description="[m] starts uniform in the square [0, area]²")
    sensing_range: float = Field(3.0, gt=0, description="[m] a robot sees the robots this close")
    gain: float = Field(0.5, gt=0, le=1, description="g of the consensus step (≤ 1 keeps every step inside the hull)")


class Spec(SpecModel):
    """A rendezvous scenario."""

    family: Literal["rendezvous"] = "rendezvous"
    name: str = ""
    robots: RobotsSpec = Field(default_factory=RobotsSpec)
    tolerance: float = Field(0.05, gt=0, description="[m] gathered when the fleet's diameter is at most this")
    max_steps: int = Field(300, ge=1)

    def run_size(self) -> RunSize:
        """One position (two float64) per robot and step, checked against the memory budget."""
        return RunSize(self.max_steps, self.robots.n, 16, "max_steps", "robots.n")
