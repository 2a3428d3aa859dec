"""The demo's analysis: pair a replayed command bag with the recorded node outputs, compare with the
core, summarize and plot. No ROS here (the recording is read back with ``rosbags``).

Angles in rad (degrees only for display), torques in N m: ``input_torque`` at the driven rocker,
motor torque before the reducer (``loads.motor_torque``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.loads import motor_torque, solve
from fourbar_ros.rules.outputs import driven_index
from fourbar_ros.rules.policy import Outcome, Policy, serve

FloatArray = npt.NDArray[np.float64]


class DemoError(FourBarError):
    """The recording does not match the replayed commands (counts or order)."""


@dataclass(frozen=True)
class DemoData:
    """One row per answered command: served theta, the node's gamma, delta (rad) and torque (N m)."""

    theta: FloatArray
    gamma: FloatArray
    delta: FloatArray
    input_torque: FloatArray
    effort: FloatArray
    rejected: int
    clamped: int


def served_angles(commands: Sequence[float], cfg: AntennaConfig) -> tuple[FloatArray, int, int]:
    """The angles the node serves for ``commands`` (rad, its policy), and the rejected and clamped counts."""
    served = serve(np.asarray(commands, dtype=np.float64), cfg.theta_min, cfg.theta_max, Policy(cfg.out_of_limits),
                   cfg.linkage.reach())
    rejected = sum(n for outcome, n in served.outcomes.items() if outcome.rejected)
    return served.theta, rejected, served.outcomes[Outcome.CLAMPED]


def pair(commands: Sequence[float], cfg: AntennaConfig, joint_states: Sequence[Any],
         torques: Sequence[Any]) -> DemoData:
    """Match the i-th answered command with the i-th JointState and input_torque message (in order)."""
    served, rejected, clamped = served_angles(commands, cfg)
    if len(joint_states) != len(served) or len(torques) != len(served):
        raise DemoError(f'{len(served)} commands answered but {len(joint_states)} joint_states and '
                        f'{len(torques)} input_torque messages recorded')
    driven = driven_index(cfg)
    return DemoData(
        theta=served,
        gamma=np.array([m.position[0] for m in joint_states], dtype=np.float64),
        delta=np.array([m.position[1] for m in joint_states], dtype=np.float64),
        input_torque=np.array([m.data for m in torques], dtype=np.float64),
        effort=np.array([m.effort[driven] for m in joint_states], dtype=np.float64),
        rejected=rejected, clamped=clamped)


def core_deviation(data: DemoData, cfg: AntennaConfig) -> tuple[float, float]:
    """Largest |node - core| over the rows: (rocker angles, rad; torque, N m)."""
    angle, torque = 0.0, 0.0
    for theta, gamma, delta, tau, effort in zip(data.theta, data.gamma, data.delta, data.input_torque,
                                                data.effort, strict=True):
        state = solve(cfg, float(theta))
        angle = max(angle, abs(gamma - float(state.gamma)), abs(delta - float(state.delta)))
        torque = max(torque, abs(tau - float(state.input_torque)), abs(effort - float(state.input_torque)))
    return angle, torque


def _deg(x: float) -> str:
    return f'{math.degrees(x):+.2f} deg'


def summary_lines(data: DemoData, cfg: AntennaConfig, diagnostics: dict[str, str]) -> list[str]:
    """The demo's short report: rocker angle ranges, peak torques against the limits, rejections."""
    if data.theta.size == 0:
        return ['no command was answered']
    peak = int(np.argmax(np.abs(data.input_torque)))
    tau = float(data.input_torque[peak])
    tau_motor = motor_torque(cfg, tau)
    driven = cfg.driven.value
    rejected_diag = sum(int(diagnostics.get(k, '0')) for k in (
        'commands_rejected_not_finite', 'commands_rejected_out_of_limits', 'commands_rejected_out_of_reach'))
    return [
        f'theta    {_deg(float(data.theta.min()))} .. {_deg(float(data.theta.max()))} '
        f'({data.theta.size} commands served)',
        f'gamma    {_deg(float(data.gamma.min()))} .. {_deg(float(data.gamma.max()))}   (rocker AB, at A)',
        f'delta    {_deg(float(data.delta.min()))} .. {_deg(float(data.delta.max()))}   (rocker CD, at D)',
        f'torque   peak {abs(tau):.4f} N m at the driven rocker ({driven}) at theta {_deg(float(data.theta[peak]))}'
        f' for a {cfg.load_torque:g} N m load: {100 * abs(tau) / cfg.output_torque_limit:.0f}% of the '
        f'{cfg.output_torque_limit:g} N m reducer rating',
        f'motor    peak {abs(tau_motor):.5f} N m through {cfg.reducer_ratio:g}:1 at efficiency '
        f'{cfg.reducer_efficiency:g}: {100 * abs(tau_motor) / cfg.motor_torque_limit:.0f}% of the '
        f'{cfg.motor_torque_limit:g} N m motor limit',
        f'rejected {data.rejected} commands by the limits (node diagnostics: {rejected_diag} rejected, '
        f'{diagnostics.get("commands_clamped", "?")} clamped of {diagnostics.get("commands_received", "?")} '
        'received)',
    ]


def plot(data: DemoData, cfg: AntennaConfig, path: Path, title: str) -> Path:
    """Write a PNG: gamma and delta (deg), and the driven rocker's torque (N m) against theta (deg)."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    order = np.argsort(data.theta, kind='stable')
    theta_deg = np.degrees(data.theta[order])
    grid = np.linspace(cfg.theta_min, cfg.theta_max, 400)
    core = [solve(cfg, float(t)) for t in grid]
    grid_deg = np.degrees(grid)

    fig, (ax_angle, ax_torque) = plt.subplots(2, 1, figsize=(8.0, 7.0), sharex=True, layout='constrained')
    # Recorded samples as rings, the core as a thin line through them: the line must run through
    # every ring.
    ring = {'marker': 'o', 'ms': 4, 'mfc': 'none', 'mew': 0.6, 'ls': 'none'}
    ax_angle.plot(theta_deg, np.degrees(data.gamma[order]), color='tab:blue', label='gamma, recorded from the node',
                  **ring)
    ax_angle.plot(theta_deg, np.degrees(data.delta[order]), color='tab:orange',
                  label='delta, recorded from the node', **ring)
    ax_angle.plot(grid_deg, [math.degrees(float(s.gamma)) for s in core], color='k', lw=0.8,
                  label='gamma and delta, core')
    ax_angle.plot(grid_deg, [math.degrees(float(s.delta)) for s in core], color='k', lw=0.8)
    ax_angle.set_ylabel('rocker angle (deg)')
    ax_angle.legend(loc='center right', fontsize=8)
    ax_angle.grid(True, alpha=0.3)

    driven = cfg.driven.value
    ax_torque.plot(theta_deg, data.input_torque[order], color='tab:green',
                   label=f'input torque at rocker {driven}, recorded from the node', **ring)
    ax_torque.plot(grid_deg, [float(s.input_torque) for s in core], color='k', lw=0.8, label='input torque, core')
    ax_torque.axhline(cfg.output_torque_limit, color='tab:red', ls='--', lw=1,
                      label=f'reducer rating {cfg.output_torque_limit:g} N m')
    motor_limit_at_rocker = cfg.motor_torque_limit * cfg.reducer_ratio * cfg.reducer_efficiency
    ax_torque.axhline(motor_limit_at_rocker, color='tab:purple', ls=':', lw=1,
                      label=f'motor limit {cfg.motor_torque_limit:g} N m x {cfg.reducer_ratio:g}:1')
    ax_torque.axhline(cfg.load_torque, color='0.5', ls='-.', lw=1, label=f'load {cfg.load_torque:g} N m about theta')
    ax_torque.set_ylim(0.0, 1.15 * max(cfg.output_torque_limit, motor_limit_at_rocker,
                                       float(np.max(np.abs(data.input_torque)))))
    ax_torque.set_ylabel('torque at the driven rocker (N m)')
    ax_torque.set_xlabel('antenna angle theta (deg, positive tilts down)')
    ax_torque.legend(loc='lower right', fontsize=8)
    ax_torque.grid(True, alpha=0.3)
    ratio = cfg.reducer_ratio * cfg.reducer_efficiency
    motor_axis = ax_torque.secondary_yaxis('right', functions=(lambda t: t / ratio, lambda m: m * ratio))
    motor_axis.set_ylabel('motor torque (N m)')
    fig.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f'.{path.name}.tmp')
    fig.savefig(tmp, dpi=110, format='png')
    plt.close(fig)
    tmp.replace(path)
    return path
