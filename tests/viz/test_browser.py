"""The replay page of every family in a real browser (headless Chromium over the DevTools
protocol): it loads without console errors, ``#frame=K`` shows frame K, ``<body>`` reports
the frame, frame count and robot count, two frames look different, the keyboard steps,
and a robot is drawn where its recorded position projects.

Skipped, with the reason, where Chromium or websocket-client is missing."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from PIL import Image

from robofleet.viz.replay import avoidance, coordination, flocking, search
from robofleet.viz.replay.page import write_html

BUILDERS = {"avoidance": avoidance, "avoidance_3d": avoidance, "coordination": coordination, "flocking": flocking,
            "search": search}
READY = "document.body.dataset.ready === '1'"


@pytest.fixture(scope="module")
def pages(traces, tmp_path_factory):
    """name → (scene, file URL) of every family's page."""
    folder = tmp_path_factory.mktemp("pages")
    out = {}
    for name, trace in traces.items():
        scene = BUILDERS[name].replay_scene(trace)
        out[name] = (scene, write_html(scene, folder / f"{name}.html").resolve().as_uri())
    return out


class Opened(dict):
    """name → page opened at frame 3, brought to the front when looked up (hidden tabs do not draw)."""

    def __getitem__(self, name):
        page = super().__getitem__(name)
        page.bring_to_front()
        return page


@pytest.fixture(scope="module")
def opened(browser, pages):
    out = Opened()
    for name, (scene, url) in pages.items():
        page = browser.open(url + "#frame=3")
        page.bring_to_front()
        page.wait_for(READY)
        out[name] = page
    yield out
    for page in dict.values(out):
        page.close()


def body(page) -> dict:
    return page.evaluate("Object.assign({}, document.body.dataset)")


def pixels(page) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)


def show_frame(page, k: int) -> None:
    page.evaluate(f"location.hash = 'frame={k}'")
    page.wait_for(f"document.body.dataset.frame === '{k}' && window.replay.dirty === false")
    page.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))", await_promise=True)


@pytest.mark.parametrize("name", list(BUILDERS))
def test_page_loads_without_errors_and_reports_the_fragment_frame(opened, pages, name):
    page, scene = opened[name], pages[name][0]
    assert page.errors == []
    assert body(page) == {"ready": "1", "frame": "3", "nFrames": str(scene.n_frames), "nRobots": str(scene.n_robots)}
    assert page.evaluate("document.querySelectorAll('#views canvas').length") == len(scene.views)
    legend = page.evaluate("[...document.querySelectorAll('#legend .row span')].map(e => e.textContent)")
    assert legend == [row["label"] for row in scene.legend]
    assert page.evaluate("document.getElementById('title').textContent") == scene.title


@pytest.mark.parametrize("name", list(BUILDERS))
def test_two_frames_look_different(opened, pages, name):
    page, scene = opened[name], pages[name][0]
    show_frame(page, 0)
    first = pixels(page)
    show_frame(page, scene.n_frames - 1)
    last = pixels(page)
    assert body(page)["frame"] == str(scene.n_frames - 1)
    assert (np.abs(first - last).sum(axis=-1) > 30).sum() > 50
    assert page.errors == []


def test_keys_step_play_and_the_slider_follows(opened):
    page = opened["search"]
    show_frame(page, 5)
    for key, expected in (("ArrowRight", 6), ("ArrowLeft", 5), ("End", None), ("Home", 0)):
        page.send("Input.dispatchKeyEvent", {"type": "keyDown", "key": key, "code": key})
        page.send("Input.dispatchKeyEvent", {"type": "keyUp", "key": key, "code": key})
        want = int(body(page)["nFrames"]) - 1 if expected is None else expected
        page.wait_for(f"document.body.dataset.frame === '{want}'")
        assert page.evaluate("document.getElementById('slider').value") == str(want)
    page.send("Input.dispatchKeyEvent", {"type": "keyDown", "key": " ", "code": "Space"})
    page.wait_for("Number(document.body.dataset.frame) > 0 && window.replay.playing")
    page.send("Input.dispatchKeyEvent", {"type": "keyDown", "key": " ", "code": "Space"})
    page.wait_for("!window.replay.playing")


def view_coordinates(scene, frame: int, view) -> np.ndarray:
    """``(N, 2)`` the robots' recorded coordinates in a view at ``frame``."""
    if view.source == "positions":
        return scene.positions[frame][:, list(view.axes)]
    return scene.coordinates[view.source][frame]


def free_robot(scene, frame: int, pixels_xy: np.ndarray, plot: tuple[float, float, float, float]) -> int:
    """A robot at ``frame`` drawn opaque in its own colour as a plain disc, inside the plot
    area, as far as possible from the others."""
    gaps = np.linalg.norm(pixels_xy[:, None] - pixels_xy[None], axis=-1) + np.eye(len(pixels_xy)) * 1e9
    x0, y0, x1, y1 = plot
    for i in np.argsort(-gaps.min(axis=1)):
        status = scene.statuses[int(scene.status[frame, i])] if scene.status is not None else {}
        inside = x0 + 8 < pixels_xy[i, 0] < x1 - 8 and y0 + 8 < pixels_xy[i, 1] < y1 - 8
        plain = (scene.robot_markers or ["circle"] * len(pixels_xy))[i] == "circle"
        if inside and plain and status.get("alpha", 1) == 1 and not status.get("cross"):
            return int(i)
    raise AssertionError("no robot drawn alone inside the plot")


def set_layers(page, visible: set[str]) -> None:
    script = """(visible => { for (const box of document.querySelectorAll('#layers input')) {
        if (box.checked !== visible.includes(box.dataset.group)) box.click(); } })"""
    page.evaluate(f"{script}({json.dumps(sorted(visible))})")
    page.wait_for("window.replay.dirty === false")
    page.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))", await_promise=True)


@pytest.mark.parametrize("name", list(BUILDERS))
def test_a_robot_is_drawn_where_its_recorded_position_projects(opened, pages, name):
    page, scene = opened[name], pages[name][0]
    frame = scene.n_frames // 2
    show_frame(page, frame)
    set_layers(page, {"robots"})
    for index, view in enumerate(scene.views):
        left, top, width, height, transform = page.evaluate(
            "(c => { const r = c.getBoundingClientRect(); return [r.left, r.top, r.width, r.height, c.dataset.transform]; })"
            f"(document.querySelectorAll('#views canvas')[{index}])")
        sc, ox, oy = map(float, transform.split())
        xy = view_coordinates(scene, frame, view)
        projected = np.stack([left + ox + sc * xy[:, 0], top + oy - sc * xy[:, 1]], axis=1)  # the page's stated transform
        robot = free_robot(scene, frame, projected, (left + 58, top + 8, left + width - 12, top + height - 40))
        X, Y = np.round(projected[robot]).astype(int)
        expected = np.array([int(scene.robot_fill(frame, robot)[k:k + 2], 16) for k in (1, 3, 5)])
        shot = pixels(page)
        assert np.abs(shot[Y, X] - expected).max() <= 12, (view.name, robot, shot[Y, X], expected)
        set_layers(page, set())
        assert np.abs(pixels(page)[Y, X] - expected).max() > 40, "the pixel changes when the robots are hidden"
        set_layers(page, {"robots"})
    set_layers(page, set(scene.groups()) | {"robots", "trails"})
    assert page.errors == []
