"""``robofleet reproduce search`` and ``robofleet check`` end to end (tiny budget), and the figures."""

from __future__ import annotations

from robofleet import load_scenario, simulate
from robofleet.cli.main import main
from robofleet.viz.search import animate_trace, plot_routes, plot_trace


def test_reproduce_search_writes_tables_and_plots(tmp_path):
    out = tmp_path / "repro"
    main(["reproduce", "search", "--budget", "smallest", "--executor", "serial", "--quiet", "--out", str(out)])
    for name in ("table.md", "summary.csv", "fig7.png", "coverage.png", "fig5_routes.png", "fig6_route.png"):
        assert (out / name).is_file(), name
    table = (out / "table.md").read_text()
    assert "| 3 |" in table and "(1),(2)&(3)" in table and "hexagonal" in table


def test_check_reports_every_assumption(capsys):
    main(["check", "search/fig7"])
    text = capsys.readouterr().out
    for name in ("2.1", "2.2", "2.4", "2.5", "3.1.1", "3.1.2", "3.1.3"):
        assert f"(Assumption {name}): yes" in text
    assert "complete search of A_d (Theorem 4.1, Section 3): yes" in text


def test_animation_and_route_plots(tmp_path):
    trace = simulate(load_scenario("search/failure_injection", {"max_steps": 15}), seed=1)
    gif = animate_trace(trace, tmp_path / "run.gif", max_frames=8)
    png = plot_routes(trace, tmp_path / "routes.png", robots=[0, 2])
    whole = plot_trace(trace, tmp_path / "plot.png")
    assert gif.stat().st_size > 1000 and png.stat().st_size > 1000 and whole.stat().st_size > 1000
