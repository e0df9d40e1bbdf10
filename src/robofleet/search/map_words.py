"""The word layout of a robot's map rows (:class:`.knowledge.RobotMaps`): bits per word,
words per block and layers per row. Constants only, so the scenario's memory budget
(:mod:`robofleet.search.spec`) is computed without loading the compiled map kernels."""

WORD = 64
"""Vertices per word of a map row (one bit each)."""
BLOCK_WORDS = 4
"""Words per block of a map row (256 vertices per layer)."""
LAYERS = 4
"""Layers of a map row: visited, discovered, blocked, sensed."""
