"""Subcommands of the `fourbar` command line; each module here is one subcommand (see fourbar_ros.cli)."""
