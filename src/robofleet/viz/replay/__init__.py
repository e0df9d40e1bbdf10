"""Replays of runs: a family-independent :class:`~robofleet.viz.replay.scene.Scene` built
by each family's ``replay_scene(trace)``, drawn by a self-contained HTML page
(:mod:`~robofleet.viz.replay.page`) or written as a Rerun recording
(:mod:`~robofleet.viz.replay.rerun_export`); reproduction reports
(:mod:`~robofleet.viz.replay.report`); a headless-Chromium driver for checking and
screenshotting pages (:mod:`~robofleet.viz.replay.browser`)."""

from __future__ import annotations

import importlib
from collections.abc import Callable

from ...core.errors import ConfigError

MAX_FRAMES = 1500
"""Frames of a replay at most (longer runs show every k-th recorded state)."""


def scene_builder(family: str) -> Callable:
    """``replay_scene(trace, max_frames=...)`` of a family: the function of the module
    ``robofleet.viz.replay.<family>``.

    Raises
    ------
    ConfigError
        The family has no replay module.
    """
    try:
        module = importlib.import_module(f"{__name__}.{family}")
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{family}":
            raise
        raise ConfigError(f"family {family!r}: replay: expected a module {__name__}.{family}, received none") from None
    return module.replay_scene
