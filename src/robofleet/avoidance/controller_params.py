"""The parameter blocks of the scenario's controllers: ``orca:`` (:mod:`.orca`, van den Berg
et al.'s reciprocal velocity obstacles) and ``mpc:`` (:mod:`.mpc`, the B-UAVC MPC of
appendix C). Parameters only, so a scenario file is read without loading the compiled
kernels or the solvers; :mod:`.orca` and :mod:`.mpc` re-export them."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from ..core.config import SpecModel


class OrcaParams(SpecModel):
    """ORCA parameters (names as in the paper's reference library)."""

    neighbor_dist: float = Field(3.0, gt=0, description="sensing range for neighbours [m]")
    max_neighbors: int = Field(10, ge=1, description="neighbours considered per agent")
    time_horizon: float = Field(2.0, gt=0, description="τ: collision-free horizon w.r.t. agents [s]")
    time_horizon_obst: float = Field(2.0, gt=0, description="τ_o: collision-free horizon w.r.t. static obstacles and walls, at least Δt to keep robots out of them [s]")


class MPCConfig(SpecModel):
    """Parameters of the B-UAVC MPC."""

    horizon: int = Field(10, gt=0, description="N, number of predicted steps")
    max_constraints: int = Field(12, gt=0, description="cell rows the problem is built for ('ipopt' and linear models; "
                                 "'rti' keeps every row the plan can reach)")
    input_weight: float = Field(1e-3, ge=0, description="w_u")
    deadlock_steps: int = Field(20, gt=0, description="n_dead")
    deadlock_progress: float = Field(0.2, ge=0, description="Δp_min [m]: least net displacement over n_dead steps")
    recover_steps: int = Field(10, gt=0, description="steps with the rotated goal")
    max_iter: int = Field(30, gt=0, description="IPOPT iteration cap (nonlinear models)")
    solver: Literal["ipopt", "rti"] = Field("rti", description="nonlinear models: 'rti' (braking-safe condensed "
                                            "Gauss-Newton SQP around the shifted plan, DAQP QPs, robofleet.avoidance.rti) "
                                            "or 'ipopt' (the full NLP)")
    sqp_iterations: int = Field(3, gt=0, description="most QPs per solve on the 'rti' path (1 = pure real-time iteration)")
    terminal_rest: bool = Field(True, description="quadrotor: the plan ends at rest, level (v_N = 0, φ_N = θ_N = 0)")
    rest_tolerance: float = Field(0.02, gt=0, description="|v_N|, |φ_N|, |θ_N| bound of terminal_rest [m/s, rad]")
    noise_band: float = Field(2.0, ge=0, description="'rti' path: soft tightening of stages 2…N, in units of the "
                              "robot's position σ")
