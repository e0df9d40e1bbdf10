"""The ``scheduler:`` block of a flocking scenario (FSYNC, SSYNC or ASYNC activations, Sec. 3.2
and 4.2): parameters only, so a scenario file is read without loading the compiled
Look-Compute-Move loop of :mod:`.schedulers`."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from ..core.config import SpecModel
from ..core.errors import ScenarioError


class SchedulerSpec(SpecModel):
    """Scheduler parameters (time unit = one leader move, as in Sec. 4.2)."""

    kind: Literal["fsync", "ssync", "async"] = "async"
    activation_probability: float = Field(default=0.5, gt=0.0, le=1.0)
    cycle_min: float = Field(default=0.5, gt=0.0)
    cycle_max: float = Field(default=1.5, gt=0.0)
    rigidity: float = Field(default=1.0, gt=0.0, le=1.0)
    min_move: float = Field(default=0.01, gt=0.0)

    @model_validator(mode="after")
    def _bounds(self):
        if self.cycle_max < self.cycle_min:
            raise ScenarioError("cycle_max", f"a value >= cycle_min ({self.cycle_min})", self.cycle_max)
        return self

    @property
    def move_time_max(self) -> float:
        """Longest possible Move (max_j τ_f^M(j) of Sec. 3.2)."""
        return self.cycle_max if self.kind == "async" else 1.0

    @property
    def move_time_min(self) -> float:
        return self.cycle_min if self.kind == "async" else 1.0
