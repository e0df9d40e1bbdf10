"""The family value the rest of robofleet reads."""

from robofleet.core.family import Family

from .guarantees import check
from .metrics import RESULTS
from .simulation import simulate
from .spec import Spec

FAMILY = Family(
    name="rendezvous",
    title="rendezvous by range-limited consensus",
    paper="a worked example of the family contract",
    spec=Spec,
    simulate=simulate,
    check=check,
    viz="rendezvous.viz",
    budget="max_steps",
    results=RESULTS,
)
