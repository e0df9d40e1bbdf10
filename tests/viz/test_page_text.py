"""Names that look like the page template's placeholders (``__DATA__``, ``__JS__`` …) or
like HTML (``</script>``, ``<!--<script>``) appear literally in the replay page and in a
reproduction's report, and do not break either: every placeholder is filled once, the
embedded data parses back to the scene, and a browser shows the name as written."""

from __future__ import annotations

import html
import json
import re

import pytest

import robofleet
from robofleet.scenarios import FAMILIES
from robofleet.viz.replay import scene_builder
from robofleet.viz.replay.page import asset, replay_html, write_html
from robofleet.viz.replay.report import report_html

PLACEHOLDER_NAMES = ["__DATA__", "__TITLE__ __CSS__ __JS__ __VERSION__", "</script><!--<script>", "\\1 \\g<0> $& & <b>x</b>",
                     "__DATA____DATA__"]


@pytest.fixture(scope="module")
def trace():
    spec = robofleet.load_scenario("search/failure_injection", {FAMILIES["search"].budget: 6})
    return robofleet.simulate(spec, seed=1)


def named_scene(trace, name: str):
    trace.metadata["scenario"] = name
    trace.metadata["algorithm"] = f"method {name}"
    return scene_builder(trace.family)(trace)


def embedded_data(page: str) -> dict:
    scripts = re.findall(r'<script type="application/json" id="replay-data">(.*?)</script>', page, flags=re.S)
    assert len(scripts) == 1
    return json.loads(scripts[0])


@pytest.mark.parametrize("name", PLACEHOLDER_NAMES)
def test_a_placeholder_like_name_is_written_literally_and_fills_nothing(trace, name):
    scene = named_scene(trace, name)
    assert name in scene.title
    page = replay_html(scene)
    assert page.count(asset("replay.js")) == 1 and page.count(asset("replay.css")) == 1
    assert page.count("</script>") == 2 and page.count("<script") == 2  # the data and the script, nothing opened by the name
    assert re.search(r"<title>(.*?)</title>", page, flags=re.S).group(1) == html.escape(scene.title)
    assert f'<h1 id="title">{html.escape(scene.title)}</h1>' in page
    data = embedded_data(page)
    assert data["title"] == scene.title and data == json.loads(json.dumps(scene.to_document()))
    for piece in re.split(r"__(?:VERSION|TITLE|CSS|JS|DATA)__", asset("template.html")):
        assert piece in page  # the template's own text is all there, unchanged


def test_a_reproduction_report_shows_placeholder_like_names_literally(tmp_path):
    name = "__DATA__ <script><!-- & <b>"  # a folder name: no "/"
    directory = tmp_path / name
    directory.mkdir()
    (directory / "summary.csv").write_text("table,n\nt,1\n")
    (directory / "table.md").write_text(f"# {name}\n\n| method | rate |\n|---|---|\n| `{name}` | </script> __JS__ |\n")
    page = report_html(directory)
    assert f"<title>{html.escape(name)}</title>" in page
    assert f"<h1>{html.escape(name)}: reproduction report</h1>" in page
    assert f"<td><code>{html.escape(name)}</code></td><td>&lt;/script&gt; __JS__</td>" in page
    assert "<script" not in page and "<!--" not in page


def test_a_browser_shows_the_name_as_written(trace, browser, tmp_path):
    for index, name in enumerate(PLACEHOLDER_NAMES):
        scene = named_scene(trace, name)
        page = browser.open(write_html(scene, tmp_path / f"{index}.html").resolve().as_uri())
        page.bring_to_front()
        page.wait_for("document.body.dataset.ready === '1'")
        assert page.errors == []
        assert page.evaluate("document.title") == scene.title
        assert page.evaluate("document.getElementById('title').textContent") == scene.title
        assert page.evaluate("document.body.dataset.nFrames") == str(scene.n_frames)
        page.close()
