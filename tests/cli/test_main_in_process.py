"""``main`` called again in one process reuses the click command typer built, and still
sees a command registered on the application after the first call."""

from __future__ import annotations

import pytest

from robofleet.cli import main as cli


def test_a_second_call_reuses_the_built_command(capsys):
    cli.main(["scenarios"])
    built = cli.click_command.cache_info().currsize
    hits = cli.click_command.cache_info().hits
    cli.main(["scenarios"])
    assert cli.click_command.cache_info().hits == hits + 1 and cli.click_command.cache_info().currsize == built
    assert "avoidance/circle_swap" in capsys.readouterr().out


def test_a_command_registered_after_the_first_call_is_run(monkeypatch, capsys):
    cli.main(["scenarios"])
    monkeypatch.setattr(cli.app, "registered_commands", list(cli.app.registered_commands))
    cli.app.command("hello-from-test", hidden=True)(lambda: print("hello"))
    cli.main(["hello-from-test"])
    assert capsys.readouterr().out.endswith("hello\n")
    with pytest.raises(SystemExit) as stop:
        cli.main(["no-such-command"])
    assert stop.value.code == 2
