"""The ``robofleet`` command line. Thin: every command calls the public Python API.

Family packages add their own commands (``reproduce <name>``, ``check`` ...) through a
``register(app, reproduce)`` function in ``robofleet/cli/<family>.py``.
"""

from __future__ import annotations

import importlib
import sys

import typer

from ..core.errors import RobofleetError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Decentralized multi-robot coordination.")
reproduce = typer.Typer(no_args_is_help=True, help="Reproduce a paper's experiment (sweep + plots + markdown table).")
app.add_typer(reproduce, name="reproduce")

FAMILY_CLIS = ("common", "avoidance", "avoidance_models", "coordination", "flocking", "search")


def _register_family_commands() -> None:
    for name in FAMILY_CLIS:
        modname = f"robofleet.cli.{name}"
        try:
            module = importlib.import_module(modname)
        except ModuleNotFoundError as exc:  # a family not built yet; any other import error is a bug
            if exc.name != modname:
                raise
            continue
        module.register(app, reproduce)


_register_family_commands()


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning robofleet errors into one line and exit status 2."""
    try:
        app(args=argv, standalone_mode=False)
    except RobofleetError as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("interrupted; finished results are kept", err=True)
        sys.exit(130)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except Exception as exc:
        # usage errors: typer raises its own copies of click's exception classes, so they
        # are recognised by what they can do (show themselves, carry an exit code)
        show, code = getattr(exc, "show", None), getattr(exc, "exit_code", None)
        if callable(show) and isinstance(code, int):
            show()
            sys.exit(code)
        raise


if __name__ == "__main__":
    main()
