"""Helpers shared by the CLI tests."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from gridmap_cli.cli import cli


def run(*args: str) -> tuple[int, str, str]:
    """Run ``gridmap ARGS`` in-process: exit code, stdout, stderr.

    An unexpected exception (not click's SystemExit) is re-raised, so that a crash shows its
    traceback instead of passing as a non-zero exit.
    """
    result = CliRunner().invoke(cli, list(args))
    if result.exception and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.stdout, result.stderr


def names(folder: Path) -> set[str]:
    """Names of the entries of ``folder``: what a command left behind."""
    return {p.name for p in folder.iterdir()}
