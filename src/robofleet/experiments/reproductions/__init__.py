"""The declared reproductions, one module per paper experiment (see
:mod:`robofleet.experiments.reproduction`). :data:`REPRODUCTIONS` is their table, keyed
by the name ``robofleet reproduce NAME`` takes."""

from __future__ import annotations

from ..reproduction import Reproduction
from .buavc import REPRODUCTION as BUAVC
from .buavc_models import REPRODUCTION as BUAVC_MODELS
from .coordination_peers import REPRODUCTION as COORDINATION_PEERS
from .flocking import REPRODUCTION as FLOCKING
from .rmtrack import REPRODUCTION as RMTRACK
from .search import REPRODUCTION as SEARCH

REPRODUCTIONS: dict[str, Reproduction] = {r.name: r for r in (BUAVC, BUAVC_MODELS, RMTRACK, COORDINATION_PEERS, FLOCKING, SEARCH)}
