"""Optional dependencies: which extra provides what, and one-line errors when one is missing.

``pip install 'robofleet[mpc]'`` brings casadi and daqp (the MPC controllers),
``robofleet[dask]`` the dask executor, ``robofleet[rerun]`` the Rerun export,
``robofleet[ros2]`` rclpy, the standard message packages and mcap (the ROS 2 bridge). Code that
needs one calls :func:`require` (a :class:`~robofleet.core.errors.ConfigError` naming the
extra); validation calls :func:`missing` to refuse a scenario that could not run.
"""

from __future__ import annotations

import importlib.util

from .errors import ConfigError

EXTRAS: dict[str, tuple[str, ...]] = {
    "mpc": ("casadi", "daqp"),
    "dask": ("distributed",),
    "rerun": ("rerun",),
    "ros2": ("rclpy", "geometry_msgs", "nav_msgs", "std_msgs", "visualization_msgs", "mcap"),
}
"""Each extra and the modules it installs."""


def is_installed(module: str) -> bool:
    """Whether ``module`` can be imported (without importing it)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a parent package missing, or a module set to None
        return False


def missing(extra: str) -> list[str]:
    """The modules of ``extra`` that are not installed (empty when all are)."""
    return [module for module in EXTRAS[extra] if not is_installed(module)]


def install_hint(extra: str) -> str:
    """``pip install 'robofleet[mpc]'``."""
    return f"pip install 'robofleet[{extra}]'"


def expectation(extra: str) -> str:
    """``an installed casadi and daqp (pip install 'robofleet[mpc]')``, naming the missing modules."""
    return f"an installed {' and '.join(missing(extra) or EXTRAS[extra])} ({install_hint(extra)})"


def require(extra: str, what: str) -> None:
    """Raise a one-line :class:`ConfigError` naming the extra when one of its modules is missing."""
    if missing(extra):
        raise ConfigError(f"{what}: expected {expectation(extra)}, received none")
