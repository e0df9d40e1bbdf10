"""Replays of a run that keeps every 10th step (``record_every: 10``): frame k shows the state
after step 10k, is labelled step 10k at time 10k·dt, speeds are over 10·dt, and its events
are those of the steps it covers (since the frame before it); the page embeds the events
as columns, the Rerun recording puts robots and events at those times, and a browser shows
the step on the clock."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

import robofleet
from robofleet.core.trace import Trace
from robofleet.viz.replay import avoidance, coordination, search
from robofleet.viz.replay.building import replay_frames
from robofleet.viz.replay.page import write_html
from robofleet.viz.replay.scene import decode_array

EVERY = 10


@pytest.fixture(scope="module")
def runs():
    """The same run kept every step and every 10th step (an avoidance run with deadlock events)."""
    spec = {"max_steps": 150, "robots.n": 12}
    full = robofleet.simulate(robofleet.load_scenario("avoidance/circle_swap", spec), seed=3)
    kept = robofleet.simulate(robofleet.load_scenario("avoidance/circle_swap", {**spec, "record_every": EVERY}), seed=3)
    return full, kept


def covered_steps(scene_steps: np.ndarray, frame: int) -> range:
    """The steps frame ``frame`` covers: those after the frame before it, up to its own
    (frame 0: step 0; the last frame also takes the steps after it)."""
    first = 0 if frame == 0 else int(scene_steps[frame - 1]) + 1
    last = int(scene_steps[frame]) if frame < len(scene_steps) - 1 else 10**9
    return range(first, last + 1)


def test_frame_k_is_step_10k_at_time_10k_dt_with_the_events_of_its_steps(runs):
    full, kept = runs
    assert len(kept.events) > 0 and kept.events == full.events  # every step's events, whatever record_every
    scene = avoidance.replay_scene(kept)
    dt = kept.metadata["dt"]
    k = np.arange(scene.n_frames)
    np.testing.assert_array_equal(scene.steps, EVERY * k)
    np.testing.assert_allclose(scene.times, EVERY * k * dt)
    np.testing.assert_array_equal(scene.positions, full.positions[EVERY * k])
    wanted = {"deadlock", "empty_cell", "arrived"}
    recorded = [e for e in kept.events if e["kind"] in wanted]
    for frame in range(scene.n_frames):
        shown = sorted((e.step, e.robot, e.kind.replace(" ", "_")) for e in scene.events if e.frame == frame)
        expected = sorted((e["step"], e["robot"], e["kind"]) for e in recorded if e["step"] in covered_steps(scene.steps, frame))
        assert shown == expected, frame
    speed = next(f for f in scene.fields if f.name == "speed").values
    moved = np.linalg.norm(full.positions[EVERY * k[1:]] - full.positions[EVERY * k[:-1]], axis=-1)
    np.testing.assert_allclose(speed[1:], moved / (EVERY * dt), rtol=1e-6)  # float32, as embedded


def test_subsampled_frames_of_a_kept_run_name_their_steps(runs):
    _, kept = runs
    rows, steps = replay_frames(kept, max_frames=5)
    assert len(rows) <= 6 and rows[-1] == len(kept.positions) - 1
    np.testing.assert_array_equal(steps, rows * EVERY)
    scene = avoidance.replay_scene(kept, max_frames=5)
    assert scene.steps.tolist() == steps.tolist() and any("every 10 steps" in note for note in scene.notes)


def kept_every(trace: Trace, every: int, per_step: tuple[str, ...]) -> Trace:
    """The trace as a run keeping every ``every``-th step would hold it: rows 0, k, 2k, … of
    the state and ``per_step`` arrays (the families without ``record_every`` in their scenarios)."""
    arrays = {k: (a[::every] if k in per_step else a) for k, a in trace.arrays.items()}
    return Trace(trace.family, arrays, trace.events, {**trace.metadata, "record_every": every}, trace.results, trace.workspace)


@pytest.mark.parametrize("scenario, overrides, builder, per_step", [
    ("coordination/x_corridor_5_tff", {"simulation.max_steps": 400}, coordination, ("positions", "progress", "waiting", "disturbed")),
    ("search/failure_injection", {"max_steps": 40}, search, ("positions", "vertex", "time"))])
def test_other_families_label_frames_with_their_steps(scenario, overrides, builder, per_step, tmp_path):
    full = robofleet.simulate(robofleet.load_scenario(scenario, overrides), seed=2)
    trace = Trace.load(kept_every(full, 4, per_step).save(tmp_path / "run"))  # a valid trace of record_every 4
    scene = builder.replay_scene(trace)
    np.testing.assert_array_equal(scene.steps, 4 * np.arange(scene.n_frames))
    np.testing.assert_array_equal(scene.positions, full.positions[scene.steps])
    for e in scene.events:
        assert e.step in covered_steps(scene.steps, e.frame)
    if builder is search:
        visited = search.first_visit_frames(trace, scene.steps)
        vertex = trace.arrays["vertex"][..., 0]
        for v in np.unique(vertex):  # the frame of the first kept row standing on it
            assert visited[v] == np.argmax((vertex == v).any(axis=1))


def test_the_page_embeds_events_as_columns(runs):
    _, kept = runs
    scene = avoidance.replay_scene(kept)
    doc = scene.to_document()["events"]
    assert set(doc) == {"kinds", "texts", "frame", "kind", "robot", "step", "text"}
    np.testing.assert_array_equal(decode_array(doc["frame"]), scene.events.frame)
    np.testing.assert_array_equal(decode_array(doc["step"]), scene.events.step)
    assert np.all(np.diff(decode_array(doc["frame"])) >= 0)  # ordered by frame, as the page expects


@pytest.mark.skipif(importlib.util.find_spec("rerun") is None, reason="the rerun extra is not installed")
def test_the_recording_puts_frames_and_events_at_their_steps_times(runs, tmp_path):
    from tests.viz.test_rerun import read_back
    from robofleet.viz.replay.rerun_export import write_rrd

    _, kept = runs
    scene = avoidance.replay_scene(kept)
    entities = read_back(write_rrd(scene, tmp_path / "run.rrd"))
    seconds = lambda times: sorted(round(t / np.timedelta64(1, "ms")) / 1000 if isinstance(t, np.timedelta64) else round(t.total_seconds(), 3)
                                   for t in times)  # noqa: E731
    assert seconds(entities["/world/robots"]["times"]) == [round(float(t), 3) for t in scene.times]
    assert set(seconds(entities["/world/events"]["times"])) == {round(float(scene.times[f]), 3) for f in scene.events.frame}


def test_a_browser_shows_the_step_of_the_frame(runs, browser, tmp_path):
    _, kept = runs
    scene = avoidance.replay_scene(kept)
    page = browser.open(write_html(scene, tmp_path / "kept.html").resolve().as_uri() + "#frame=3")
    page.bring_to_front()
    page.wait_for("document.body.dataset.ready === '1'")
    assert page.errors == []
    clock = page.evaluate("document.getElementById('clock').textContent")
    assert f"step {3 * EVERY}" in clock and f"t = {3 * EVERY * kept.metadata['dt']:g}" in clock
    listed = page.evaluate("[...document.querySelectorAll('#events .event')].map(e => e.textContent)")
    assert listed and all("step " in line for line in listed)
    page.close()
