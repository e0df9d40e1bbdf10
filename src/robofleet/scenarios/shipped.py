"""The scenario files shipped with robofleet (``scenarios/<family>/`` in a checkout,
``robofleet/_scenarios/<family>/`` in an installed wheel)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path


def shipped_scenario(family: str, name: str) -> Path:
    """Path of the shipped scenario ``scenarios/<family>/<name>``.

    A checkout's own ``scenarios/`` folder wins (so edits are picked up); otherwise the
    copy packaged into the wheel.
    """
    checkout = Path(__file__).resolve().parents[3] / "scenarios" / family / name
    if checkout.exists():
        return checkout
    return Path(str(resources.files("robofleet") / "_scenarios" / family / name))
