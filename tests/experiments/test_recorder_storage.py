"""The recorder's arrays: counted against the memory budget for the whole step budget when
declared, stored only as far as the run writes them, and read as if all rows existed."""

from __future__ import annotations

import numpy as np
import pytest

from robofleet.core.budget import MEMORY_BUDGET_VARIABLE
from robofleet.core.errors import ConfigError
from robofleet.core.recorder import FIRST_ROWS, RecordedArray, Recorder


def test_a_run_that_stops_early_stores_a_few_doublings_of_its_rows_not_its_budget():
    rec = Recorder(max_steps=30_000, n_robots=2)
    rec.state("x", (2,), initial=[0.0, 0.0])
    rec.step("u", (2,))

    def step(k):
        rec.put(k, u=[k, -k])
        rec.put_state(k + 1, x=rec["x"][k] + 1.0)
        return k == 999

    assert rec.run(step) == 1000
    assert len(rec["x"].data) < 2 * 1001 and len(rec["u"].data) < 2 * 1000
    arrays = rec.arrays()
    np.testing.assert_array_equal(arrays["x"][:, 0], np.arange(1001.0))
    np.testing.assert_array_equal(arrays["u"][:, 1], -np.arange(1000.0))
    assert len(arrays["step_seconds"]) == 1000 and np.isnan(arrays["step_seconds"]).all()  # never timed


def test_rows_never_written_hold_the_fill_value():
    rec = Recorder(max_steps=5_000, n_robots=1)
    rec.step("flag", (1,), dtype=bool, fill=False)
    rec.step("value", (1,))
    rec.put(3, flag=[True])
    rec.run(lambda k: k == 1_999)
    arrays = rec.arrays()
    assert arrays["flag"].shape == (2_000, 1) and arrays["flag"][:, 0].tolist() == [k == 3 for k in range(2_000)]
    assert np.isnan(arrays["value"]).all()


@pytest.mark.parametrize("key", [7, -1, slice(300, 520), slice(None), (slice(600, 602), 0), np.array([5, 700]), Ellipsis])
def test_indexing_reads_and_writes_as_the_array_of_all_rows(key):
    full = np.full((1_000, 2), np.nan)
    grown = RecordedArray(1_000, (2,), float, np.nan)
    assert len(grown.data) == FIRST_ROWS
    values = np.arange(full[key].size, dtype=float).reshape(full[key].shape)
    full[key] = values
    grown[key] = values
    np.testing.assert_array_equal(grown[key], full[key])
    np.testing.assert_array_equal(grown.head(1_000), full)
    assert grown.shape == full.shape and len(grown) == len(full)


def test_the_budget_counts_the_whole_step_budget_when_an_array_is_declared(monkeypatch):
    monkeypatch.setenv(MEMORY_BUDGET_VARIABLE, "1MiB")
    rec = Recorder(max_steps=100_000, n_robots=1)  # step_seconds: 0.8 MB of the 1 MiB
    with pytest.raises(ConfigError, match="memory budget.*'positions'"):
        rec.state("positions", (1, 2))  # 100,001 rows × 16 B would not fit, though none is stored yet
