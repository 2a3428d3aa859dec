"""The antenna design check: figures on the shipped configuration against independent values, each limit failing
on its own (on both sides of its threshold), the deliberately bad configuration, and `fourbar check`."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from support.paths import REPO, TEST_DATA

from fourbar_ros.commands import main as cli_main
from fourbar_ros.config.antenna_config import config_from_values, load_config
from fourbar_ros.core.design_check import CheckLimits, _extremum, check_design, sample_curves
from fourbar_ros.core.loads import solve

SHIPPED = REPO / 'config' / 'antenna.yaml'
BAD = TEST_DATA / 'bad_antenna.yaml'

# Independent 60-digit values (test/data/turnantenna_reference.csv, upper branch) at the ends of the shipped range.
DELTA_PLUS7 = math.radians(39.390113547656)
DGAMMA_MINUS6, DGAMMA_PLUS7 = 1.518562886208, 0.916954003692
DDELTA_PLUS7 = -1.542784836266
# Reach limit: the diagonal A-D' (D' = D - h (cos t, -sin t)) equals 2 l: H^2 + h^2 - 2 H h cos t = 4 l^2.
REACH = math.acos((0.180**2 + 0.102**2 - 4 * 0.060**2) / (2 * 0.180 * 0.102))


def check_cli(*args: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli_main(['check', *args])
    out = capsys.readouterr()
    return code, out.out, out.err


# ---------------------------------------------------------------- the shipped configuration


def test_shipped_configuration_passes_with_independent_figures() -> None:
    cfg = load_config(SHIPPED)
    r = check_design(cfg)
    assert r.passed and r.failures == ()
    lo, hi = math.radians(-6.0), math.radians(7.0)
    assert r.reach_margin_low == pytest.approx(lo + REACH, rel=1e-12)
    assert r.reach_margin_high == pytest.approx(REACH - hi, rel=1e-12)
    # Driving gamma, the transmission angle is at C: its distance from a dead point is delta - theta.
    assert r.min_transmission.theta == hi
    assert math.degrees(r.min_transmission.value) == pytest.approx(math.degrees(DELTA_PLUS7 - hi), abs=1e-9)
    # Power balance: tau_in = tau_load / (d gamma/d theta); the rocker is least effective at +7 deg.
    assert r.peak_input_torque.theta == hi
    assert r.peak_input_torque.value == pytest.approx(3.5 / DGAMMA_PLUS7, rel=1e-10)
    assert r.peak_motor_torque == pytest.approx(3.5 / DGAMMA_PLUS7 / 500.0, rel=1e-10)
    assert r.max_rocker_rate.value == pytest.approx(DGAMMA_MINUS6, rel=1e-10) and r.max_rocker_rate.theta == lo
    assert r.max_other_rate.value == pytest.approx(-DDELTA_PLUS7, rel=1e-10) and r.max_other_rate.theta == hi
    assert r.max_theta_per_rocker.value == pytest.approx(1.0 / DGAMMA_PLUS7, rel=1e-10)
    # 32.39 deg is above the configured 30 deg, below the classical 40 deg: a warning, not a failure.
    assert r.transmission_limit == pytest.approx(math.radians(30.0), rel=1e-15)
    assert len(r.warnings) == 1 and '40 deg rule of thumb' in r.warnings[0]
    assert r.verdict == 'PASS (1 warning)'


def test_extrema_match_a_dense_brute_force_scan() -> None:
    """With a gravity load the torque curve is not the plain constant-load one; the reported peak must match a
    20 001-point scan through loads.solve (never below it, and not above it by more than rounding)."""
    cfg = config_from_values({'antenna_mass': 2.5, 'com_offset_normal': 0.06, 'com_offset_along': -0.03,
                              'load_torque': 0.8, 'output_torque_limit': 50.0, 'motor_torque_limit': 1.0})
    r = check_design(cfg, samples=50)
    thetas = np.linspace(cfg.theta_min, cfg.theta_max, 20001)
    states = [solve(cfg, float(t)) for t in thetas]
    torque = np.array([abs(float(s.input_torque)) for s in states])
    mu = np.array([min(float(s.transmission_angle), math.pi - float(s.transmission_angle)) for s in states])
    assert torque.max() <= r.peak_input_torque.value <= torque.max() * (1 + 1e-12)
    assert mu.min() * (1 - 1e-12) <= r.min_transmission.value <= mu.min()
    assert abs(float(solve(cfg, r.peak_input_torque.theta).input_torque)) == r.peak_input_torque.value


def test_extremum_is_refined_between_grid_points() -> None:
    theta = np.linspace(0.0, 1.0, 11)

    def f(t: float) -> float:
        return 2.0 - (t - 0.3141592653589793) ** 2

    e = _extremum(theta, np.array([f(float(t)) for t in theta]), f)
    assert e.theta == pytest.approx(0.3141592653589793, abs=1e-7)
    assert e.value == pytest.approx(2.0, abs=1e-14)


# ---------------------------------------------------------------- each limit, on both sides of its threshold


@pytest.mark.parametrize(('overrides', 'limits', 'failing'), [
    # Motor: 3.81699 N m / 500 / 0.7 = 0.010906 N m > 0.009 (a worm stage's efficiency breaks the motor margin).
    ({'reducer_efficiency': 0.7}, CheckLimits(), 'peak motor torque'),
    ({'reducer_efficiency': 0.86}, CheckLimits(), None),  # 0.008877 N m < 0.009
    # Reducer rating against the peak 3.81699 N m.
    ({'output_torque_limit': 3.8}, CheckLimits(), 'exceeds the reducer rating'),
    ({'output_torque_limit': 3.82}, CheckLimits(), None),
    # Reach margin: 32.328 deg above +7 deg, 33.328 deg below -6 deg.
    ({}, CheckLimits(min_reach_margin=math.radians(32.4)), 'reach margin at theta_max'),
    ({}, CheckLimits(min_reach_margin=math.radians(32.3)), None),
    # Transmission angle 32.390 deg at +7 deg, from the configuration or from the check's own limit.
    ({'transmission_angle_min': math.radians(32.5)}, CheckLimits(), 'minimum transmission angle 32.39 deg'),
    ({'transmission_angle_min': math.radians(32.3)}, CheckLimits(), None),
    ({}, CheckLimits(min_transmission_angle=math.radians(32.5)), 'is below the limit 32.50 deg'),
])
def test_each_limit_fails_alone(overrides: dict[str, float], limits: CheckLimits, failing: str | None) -> None:
    cfg = config_from_values(overrides)
    r = check_design(cfg, limits)
    if failing is None:
        assert r.passed, r.failures
    else:
        assert len(r.failures) == 1 and failing in r.failures[0], r.failures
        assert r.verdict.startswith('FAIL: ')


def test_the_motor_limit_uses_ratio_and_efficiency() -> None:
    cfg = config_from_values({'reducer_ratio': 250.0, 'reducer_efficiency': 0.5})
    r = check_design(cfg)
    assert r.peak_motor_torque == pytest.approx(r.peak_input_torque.value / (250.0 * 0.5), rel=1e-15)


def test_reach_margins_of_a_range_on_one_side_of_a_gap() -> None:
    """Rockers of very different length: reachable only for theta_gap <= |theta| <= theta_max."""
    cfg = config_from_values({'rocker_ab_length': 0.03, 'rocker_cd_length': 0.1, 'frame_length': 0.2,
                              'coupler_length': 0.15, 'theta_min': 0.6, 'theta_max': 0.7})
    reach = cfg.linkage.reach()
    assert reach.theta_gap > 0.0
    r = check_design(cfg)
    assert r.reach_margin_low == pytest.approx(0.6 - reach.theta_gap, rel=1e-12)
    assert r.reach_margin_high == pytest.approx(reach.theta_max - 0.7, rel=1e-12)


def test_deliberately_bad_configuration_fails() -> None:
    r = check_design(load_config(BAD))
    assert not r.passed
    assert len(r.failures) == 3
    assert any('reducer rating' in f for f in r.failures)
    assert any('motor limit' in f for f in r.failures)
    assert any('transmission angle' in f for f in r.failures)
    assert r.peak_input_torque.theta == pytest.approx(math.radians(15.0), rel=1e-15)


# ---------------------------------------------------------------- the command line


def test_cli_shipped_passes_and_bad_fails(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = check_cli('--params', str(SHIPPED), capsys=capsys)
    assert code == 0, err
    assert 'verdict: PASS' in out and 'peak input torque' in out and 'reach margin' in out
    code, out, _ = check_cli('--params', str(BAD), capsys=capsys)
    assert code == 1 and 'verdict: FAIL: ' in out


def test_cli_json(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = check_cli('--params', str(SHIPPED), '--json', capsys=capsys)
    assert code == 0
    v = json.loads(out)
    assert v['passed'] is True and v['failures'] == []
    assert {'reach_margin_low', 'reach_margin_high', 'min_transmission_angle', 'peak_input_torque',
            'peak_motor_torque', 'max_rocker_rate', 'max_theta_per_rocker', 'verdict'} <= set(v)
    assert v['peak_input_torque']['value'] == pytest.approx(3.5 / DGAMMA_PLUS7, rel=1e-10)
    code, out, _ = check_cli('--params', str(BAD), '--json', capsys=capsys)
    assert code == 1 and json.loads(out)['passed'] is False


def test_cli_flags_override_the_file(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = check_cli('--params', str(SHIPPED), '--reducer-efficiency', '0.7', capsys=capsys)
    assert code == 1 and 'peak motor torque' in out
    code, out, _ = check_cli('--params', str(BAD), '--theta-max', '7', '--deg', capsys=capsys)
    assert code == 0, out
    code, out, _ = check_cli('--frame', '0.18', '--rocker', '0.06', '--coupler', '0.102', '--theta-min', '-6',
                             '--theta-max', '7', '--deg', '--min-transmission-angle', '35', capsys=capsys)
    assert code == 1 and 'below the limit 35.00 deg' in out


@pytest.mark.parametrize(('args', 'match'), [
    (['--params', 'no/such/file.yaml'], 'no/such/file.yaml: cannot read'),
    (['--reducer-efficiency', '2.0'], 'reducer_efficiency'),
    (['--theta-max', '60', '--deg'], 'out of the linkage reach'),
    (['--theta-max', '20', '--deg'], 'dead point'),
    (['--frame', '1.0'], 'do not form a linkage'),
    (['--min-reach-margin', 'nan'], 'must be finite'),
    (['--samples', '1'], 'between 2 and 100000'),
    (['--samples', '100000001'], 'between 2 and 100000'),
    (['--samples', '1e8'], 'between 2 and 100000'),
    (['--plot', 'out.jpg'], 'must end in .png'),
    (['--plot', 'no/such/dir/out.png'], 'directory does not exist'),
])
def test_cli_bad_input_exits_2_with_one_line(args: list[str], match: str, capsys: pytest.CaptureFixture[str],
                                             tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, out, err = check_cli(*args, capsys=capsys)
    assert code == 2 and out == ''
    assert err.startswith('fourbar check: error: ') and err.count('\n') == 1 and match in err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_cli_plot_writes_a_png_atomically(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / 'check.png'
    code, out, _ = check_cli('--params', str(BAD), '--plot', str(target), capsys=capsys)
    assert code == 1 and f'plot: {target}' in out
    assert target.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and target.stat().st_size > 20_000
    assert [p.name for p in tmp_path.iterdir()] == ['check.png']  # no temporary file left behind


def test_plot_curves_cover_the_range() -> None:
    cfg = load_config(SHIPPED)
    c = sample_curves(cfg, 10)
    assert c.theta[0] == cfg.theta_min and c.theta[-1] == cfg.theta_max and c.theta.size == 11
    assert np.all(np.isfinite(c.input_torque)) and np.all(c.motor_torque == c.input_torque / 500.0)


def test_console_script_exit_status() -> None:
    """As CI would use it: a separate process, exit 1 on the bad configuration."""
    bad = subprocess.run([sys.executable, '-m', 'fourbar_ros.commands', 'check', '--params', str(BAD)],
                         capture_output=True, text=True, cwd=REPO, timeout=120, check=False)
    assert bad.returncode == 1 and 'verdict: FAIL' in bad.stdout, bad.stderr
    ok = subprocess.run([sys.executable, '-m', 'fourbar_ros.commands', 'check', '--params', str(SHIPPED)],
                        capture_output=True, text=True, cwd=REPO, timeout=120, check=False)
    assert ok.returncode == 0 and 'verdict: PASS' in ok.stdout, ok.stderr


def test_report_is_frozen_data() -> None:
    r = check_design(load_config(SHIPPED))
    with pytest.raises(AttributeError):
        r.failures = ('x',)  # type: ignore[misc]
    assert replace(r, failures=('x',)).passed is False
