"""The navigation stages' parameters, one block per stage, and their defaults: the one
place they live (the scenario's ``navigation:`` block takes its defaults from here)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .band import BandParams
from .detour import DetourParams
from .right_hand import RightHandParams
from .route import RouteParams
from .yielding import YieldingParams


@dataclass(frozen=True)
class NavigationParams:
    """Which navigation stages run and their parameter blocks.

    Attributes
    ----------
    enabled: whether the navigation stages run at all (off: the paper's controller,
        appendix C alone, arrived robots hold).
    route, detour, yielding, right_hand, band: the stages' own blocks.
    """

    enabled: bool = True
    route: RouteParams = field(default_factory=RouteParams)
    detour: DetourParams = field(default_factory=DetourParams)
    yielding: YieldingParams = field(default_factory=YieldingParams)
    right_hand: RightHandParams = field(default_factory=RightHandParams)
    band: BandParams = field(default_factory=BandParams)


STAGE_BLOCKS = {"route": RouteParams, "detour": DetourParams, "yielding": YieldingParams,
                "right_hand": RightHandParams, "band": BandParams}
"""The parameter block of each configurable stage, by its key in ``navigation:``."""

LIVENESS_PLACES = {
    "enabled": "enabled", "roadmap": "route.enabled", "passage_sigmas": "route.passage_sigmas",
    "near": "yielding.near", "linger_steps": "yielding.linger_steps", "aside": "yielding.aside",
    "max_aside": "yielding.max_aside", "aside_turn": "yielding.aside_turn", "clear_steps": "yielding.clear_steps",
    "max_yield_steps": "yielding.max_yield_steps", "still_radius": "yielding.still_radius",
    "still_steps": "yielding.still_steps", "return_steps": "yielding.return_steps",
    "right_hand_angle": "right_hand.angle", "face_near": "right_hand.face_near",
    "detour": "detour.enabled", "detour_steps": "detour.steps", "band_sigmas": "band.sigmas",
}
"""Where each field of a flat ``liveness:`` block belongs under ``navigation:`` (named by the error it gets)."""


def from_mapping(data: dict) -> NavigationParams:
    """:class:`NavigationParams` from a nested mapping (``{"enabled": …, "route": {…}, …}``)."""
    blocks = {key: cls(**data[key]) for key, cls in STAGE_BLOCKS.items() if key in data}
    return NavigationParams(enabled=data.get("enabled", NavigationParams.enabled), **blocks)
