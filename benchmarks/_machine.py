"""The machine line every benchmark prints first (CPU, cores, load, library versions, threads)."""

from __future__ import annotations

import os
import platform

import numba
import numpy as np


def machine() -> str:
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            model = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    load = " · load {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()) if hasattr(os, "getloadavg") else ""
    return (f"machine: {model} · {os.cpu_count()} cores{load} · python {platform.python_version()} · numpy {np.__version__}"
            f" · numba {numba.__version__}, {numba.get_num_threads()} of {numba.config.NUMBA_NUM_THREADS} threads")


def nlogn_growth(a: int, b: int) -> float:
    """The growth factor N log N predicts from ``a`` to ``b`` robots."""
    import math

    return (b * math.log(b)) / (a * math.log(a))


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description="Print the machine line the benchmarks start with.").parse_args()
    print(machine())
