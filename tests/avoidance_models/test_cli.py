"""``robofleet reproduce buavc-models`` registration and argument checks."""

import typer
from typer.testing import CliRunner

from robofleet.cli.avoidance_models import register
from robofleet.core.errors import ScenarioError


def apps():
    app, reproduce = typer.Typer(), typer.Typer()
    app.add_typer(reproduce, name="reproduce")
    register(app, reproduce)
    return app


def test_command_is_registered_with_its_options():
    result = CliRunner().invoke(apps(), ["reproduce", "buavc-models", "--help"])
    assert result.exit_code == 0
    for option in ("--seeds", "--models", "--executor", "--scheduler", "--out"):
        assert option in result.output


def test_unknown_model_name_is_rejected_before_running():
    result = CliRunner().invoke(apps(), ["reproduce", "buavc-models", "--models", "hovercraft"])
    assert isinstance(result.exception, ScenarioError)
    assert "--models" in str(result.exception) and "diff_drive" in str(result.exception)
