"""B-UAVC navigation: the stages that choose each robot's target, one module a stage
(docs/theory/buavc.md "Navigation stages").

:mod:`.pipeline` holds the one table of which stages run for which robot model, in which
order, and runs them; :mod:`.params` holds every stage's parameter block and default.
Stages only choose targets: the cell-keeping controller of each model turns the target
into a command that keeps the next state inside the robot's cell, so no stage trades the
chance constraint for liveness. Shared by every model: the goal checker (:mod:`.goal`)
and the progress checker (:mod:`.progress`).
"""

from ...core.lazy import exports

__all__ = ["NavigationParams", "PIPELINES", "StepState", "TeamNavigation", "pipeline_of"]
__getattr__, __dir__ = exports(__name__, {".params": ["NavigationParams"],
                                          ".pipeline": ["PIPELINES", "StepState", "TeamNavigation", "pipeline_of"]})
