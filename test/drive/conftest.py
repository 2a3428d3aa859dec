"""The drive tests' fixtures: ``processes`` (child processes of a real-stack test, ended with it)."""

from support.drive_stack import processes  # noqa: F401 - a fixture, found by pytest here
