"""The declared reproductions, one module per paper experiment (see
:mod:`robofleet.experiments.reproduction`). :data:`REPRODUCTIONS` is their table."""

from __future__ import annotations

from ..reproduction import Reproduction

REPRODUCTIONS: dict[str, Reproduction] = {}
