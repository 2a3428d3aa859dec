"""Negative numbers on the command line are values, as typed: `--theta -6e-1`, `--pairs -0.5,5.0 ...` (no ROS)."""

from __future__ import annotations

import argparse

import pytest
from support.cli_support import fourbar

from fourbar_ros.commands import NEGATIVE_NUMBER, build_parser


def subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _numeric(action: argparse.Action) -> type | None:
    """float or int if the option converts its text to that number type, else None."""
    if not action.option_strings or action.type is None or not callable(action.type):
        return None
    try:
        value = action.type('1')
    except (TypeError, ValueError, argparse.ArgumentTypeError):
        return None
    return type(value) if type(value) in (int, float) else None


def _required(parser: argparse.ArgumentParser, option: str) -> list[str]:
    """Arguments that make a parse succeed with ``option`` added: a placeholder for each positional, a 0 for each
    required option and for the first of each required group of exclusive options (none if ``option`` is in it)."""
    argv: list[str] = []
    for a in parser._actions:
        if not a.option_strings and a.nargs != argparse.PARSER and a.dest != 'help':
            argv.append('placeholder')
        elif a.required:
            argv += [a.option_strings[0], '0']
    for group in parser._mutually_exclusive_groups:
        members = [a.option_strings[0] for a in group._group_actions]
        if group.required and option not in members:
            argv += [members[0], '0']
    return argv


NUMERIC_OPTIONS = [(name, a.option_strings[0], a.dest, kind)
                   for name, p in sorted(subparsers().items()) for a in p._actions
                   if (kind := _numeric(a)) is not None]


def test_every_command_with_numbers_is_covered() -> None:
    names = {name for name, *_ in NUMERIC_OPTIONS}
    assert {'solve', 'check', 'design'} <= names
    assert ('solve', '--theta', 'theta', float) in NUMERIC_OPTIONS


@pytest.mark.parametrize(('command', 'option', 'dest', 'kind'), NUMERIC_OPTIONS)
def test_negative_values_of_every_numeric_option(command: str, option: str, dest: str, kind: type) -> None:
    texts = ['-2', '-0', '-007'] if kind is int else ['-6e-1', '-0.5', '-.5', '-5', '-1E+3', '-inf', '-2.5e-300']
    base = _required(subparsers()[command], option)
    for text in texts:
        argv = [command, *[t for t in base if t != option], option, text]
        if option in base:  # a required option: give it only once
            i = base.index(option)
            argv = [command, *base[:i], *base[i + 2:], option, text]
        args = build_parser().parse_args(argv)
        got = getattr(args, dest)
        want = kind(float(text)) if kind is int and 'e' in text.lower() else kind(text)
        assert type(got) is kind and got == want, (option, text, got)


@pytest.mark.parametrize('token', ['-6e-1', '-0.5,5.0', '-1,-2', '-.5', '-inf', '-nan', '-1e5,2E-3,-0.1', '-5'])
def test_negative_number_tokens(token: str) -> None:
    assert NEGATIVE_NUMBER.match(token)


@pytest.mark.parametrize('token', ['-h', '--theta', '-x1', '-1x', '-1,', '-', '--1', '-e5', '-1,a'])
def test_option_like_tokens_stay_options(token: str) -> None:
    assert not NEGATIVE_NUMBER.match(token)


def test_design_pairs_with_a_leading_minus() -> None:
    args = build_parser().parse_args(['design', '--pairs', '-0.5,5.0', '0.3,5.6', '1.2,6.1', '--pair', '-1,-2'])
    assert args.pairs == ['-0.5,5.0', '0.3,5.6', '1.2,6.1'] and args.pair == ['-1,-2']
    # As a user types them, end to end: the pairs reach the synthesis (here unbuildable without --allow-flip).
    out = fourbar('design', '--pairs', '-0.5,5.0', '0.3,5.6', '1.2,6.1')
    assert out.returncode == 2 and 'unbuildable: K1 = -0.390129' in out.stderr
    out = fourbar('design', '--allow-flip', '--json', '--pairs', '-0.5,5.0', '0.3,5.6', '1.2,6.1')
    assert out.returncode == 0, out.stderr
    assert '"crank_flipped": true' in out.stdout


def test_solve_negative_theta_as_typed() -> None:
    out = fourbar('solve', '--theta', '-6e-1', '--json')
    assert out.returncode == 0, out.stderr
    assert '"theta": -0.6' in out.stdout
    out = fourbar('solve', '--theta', '-6', '--deg', '--load-torque', '-3.5e0', '--json')
    assert out.returncode == 0, out.stderr
    assert '"load_torque": -3.5' in out.stdout


def test_check_negative_angles_as_typed() -> None:
    out = fourbar('check', '--theta-min', '-6e0', '--theta-max', '7', '--deg', '--json')
    assert out.returncode == 0, out.stderr


def test_unknown_dash_tokens_are_still_errors() -> None:
    out = fourbar('solve', '--theta', '-x1')
    assert out.returncode == 2 and 'expected one argument' in out.stderr
