"""The navigation stages' parameters, one block per stage, and their defaults: the one
place they live (the scenario's ``navigation:`` block takes its defaults from here)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class RouteParams:
    """The route stage's parameter block (:mod:`.route`).

    Attributes
    ----------
    enabled: steer to roadmap sub-goals around the obstacles.
    passage_sigmas: the noise margin of the passages, in σ of the position estimate.
    node_factor: the nodes lie ``node_factor × c`` from the obstacles.
    sight_factor: sight lines keep ``sight_factor × c`` from the obstacles.
    gap_factor: gaps narrower than ``gap_factor × (c + passage_sigmas σ)`` are closed.
    """

    enabled: bool = True
    passage_sigmas: float = 1.5
    node_factor: float = 1.15
    sight_factor: float = 0.9
    gap_factor: float = 1.8


@dataclass(frozen=True)
class DetourParams:
    """The detour stage's parameter block (:mod:`.detour`); the still test comes from
    :class:`YieldingParams` (``still_radius``, ``still_steps``), shared with the
    yielding stage.

    Attributes
    ----------
    enabled: blocked robots re-plan around neighbours that hold still.
    steps: the most steps one re-plan lasts.
    block_steps: steps a robot's own estimate must hold still before it re-plans.
    node_factor: the discs' nodes lie ``node_factor`` × the pair clearance from each neighbour.
    sight_factor: sight lines keep ``sight_factor`` × the pair clearance from each neighbour.
    """

    enabled: bool = True
    steps: int = 300
    block_steps: int = 30
    node_factor: float = 1.15
    sight_factor: float = 0.9


@dataclass(frozen=True)
class YieldingParams:
    """The yielding stage's parameter block (:mod:`.yielding`).

    Attributes
    ----------
    enabled: arrived robots yield (off: they hold at their goals, as in the paper).
    near: neighbour distance [m] that counts as lingering near a parked robot.
    linger_steps: consecutive steps a neighbour must linger before the robot yields
        (or, while it yields, before it moves further aside).
    aside: distance [m] a yielding robot moves away from the lingering neighbours.
    max_aside: largest distance [m] from its goal a yielding robot goes.
    aside_turn: how far [deg] the step aside turns counter-clockwise from straight away.
    clear_steps: steps without any neighbour within ``near`` before it returns.
    max_yield_steps: most steps one yield lasts.
    still_radius, still_steps: a neighbour whose estimate stays within ``still_radius``
        [m] of its running mean for ``still_steps`` steps holds still (parked, most
        likely) and is not yielded to (about 4σ at the shipped σ = 0.1 m). The detour
        stage shares the test. Models whose blocked robots come to rest (double
        integrators, unicycles) use radius 0: holding still does not tell a parked
        neighbour from a blocked one there.
    return_steps: most steps a robot drives back to its goal before holding again.
    parked_steps, press: a neighbour that came to rest (the still test) and has stayed
        within ``max_aside + still_radius`` of that point for ``parked_steps`` steps counts
        as parked (:class:`.progress.ParkedTest`), even while it steps aside or jitters,
        unless its estimate lies within ``press`` [m] of the robot's: a blocked robot presses
        against the parked one, at about the pair clearance 2β the cells keep (0.73 m at the
        shipped σ = 0.1 m; ``press`` adds 1.5 σ√2 for the two estimates' noise).
        ``parked_steps`` = 0 switches the test off.
    """

    enabled: bool = True
    near: float = 1.5
    linger_steps: int = 30
    aside: float = 0.6
    max_aside: float = 1.5
    aside_turn: float = 45.0
    clear_steps: int = 20
    max_yield_steps: int = 150
    still_radius: float = 0.4
    still_steps: int = 50
    return_steps: int = 200
    parked_steps: int = 150
    press: float = 0.95


@dataclass(frozen=True)
class RightHandParams:
    """The right-hand stage's parameter block (:mod:`.right_hand`).

    Attributes
    ----------
    angle: how far [deg] a robot blocked by a neighbour turns its target clockwise (0: off).
    face_near: a neighbour's face closer than this [m] to the estimate counts as blocking.
    """

    angle: float = 45.0
    face_near: float = 0.5


@dataclass(frozen=True)
class BandParams:
    """The band-return stage's parameter block (:mod:`.band`).

    Attributes
    ----------
    sigmas: the depth beyond an obstacle face, in σ of the position estimate, that sends a
        robot back into its cell (used with σ > 0 only: the deterministic methods have no band).
    """

    sigmas: float = 2.0


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
