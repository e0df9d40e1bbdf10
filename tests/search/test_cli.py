"""``robofleet reproduce search`` and ``robofleet search-check`` end to end (tiny budget)."""

from __future__ import annotations

from robofleet.cli.main import main
from robofleet.scenarios import shipped_scenario


def test_reproduce_search_writes_tables_and_plots(tmp_path, capsys):
    out = tmp_path / "repro"
    main(["reproduce", "search", "--runs", "2", "--coverage-runs", "2", "--executor", "serial", "--quiet", "--out", str(out)])
    for name in ("table.md", "fig7.png", "coverage.png", "fig5_routes.png", "fig6_route.png", "fig7_summary.csv"):
        assert (out / name).is_file(), name
    table = (out / "table.md").read_text()
    assert "| 13 |" in table and "(1),(2)&(3)" in table and "hexagonal" in table
    assert "Fig. 7" in capsys.readouterr().out


def test_search_check_reports_every_assumption(capsys):
    main(["search-check", str(shipped_scenario("search", "fig7.yaml"))])
    text = capsys.readouterr().out
    for name in ("2.4", "2.5", "3.1.1", "3.1.2", "3.1.3"):
        assert f"holds  {name}" in text
    assert "Theorem 4.1 applies" in text


def test_animation_and_route_plots(tmp_path):
    from robofleet import load_scenario, simulate
    from robofleet.viz.search import animate_trace, plot_routes

    trace = simulate(load_scenario(shipped_scenario("search", "failure_injection.yaml"), {"max_steps": 15}), seed=1)
    gif = animate_trace(trace, tmp_path / "run.gif", max_frames=8)
    png = plot_routes(trace, tmp_path / "routes.png", robots=[0, 2])
    assert gif.stat().st_size > 1000 and png.stat().st_size > 1000
