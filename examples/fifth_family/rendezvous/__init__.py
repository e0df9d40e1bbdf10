"""A fifth family, as a worked example: rendezvous by range-limited consensus.

Every robot sees the robots within ``sensing_range`` and moves to a convex combination of
its own position and theirs (docs/fifth-family.md walks through each file).
"""

from .consensus import consensus_step
from .family import FAMILY

__all__ = ["FAMILY", "consensus_step"]
