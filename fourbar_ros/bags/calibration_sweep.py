"""A synthetic calibration recording with a known truth, a slow sweep with a sensor on the antenna (no rclpy).

The tests', the benchmark's and the how-to's stand-in: the true linkage swept, an encoder with its zero off and its
counts, a Float64 or Imu sensor with its offset and noise; deterministic for a seed. See docs/how-to/calibrate.md."""

from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fourbar_ros.bags.calibration_data import IMU
from fourbar_ros.bags.storage import FLOAT64, JOINT_STATE, AtomicBagWriter, jazzy_typestore, recorded_qos
from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.calibration import GRAVITY, PARAMETER_NAMES
from fourbar_ros.core.completion import inverse_branch
from fourbar_ros.core.load_calibration import LOAD_NAMES, effort_model, load_pose
from fourbar_ros.interface.cdr import encode_float64s, encode_joint_states
from fourbar_ros.interface.stamps import seconds_to_ns, split_ns
from fourbar_ros.interface.topics import BROADCASTER_JOINT_STATES, DEFAULT_STORAGE, Storage

__all__ = ['GRAVITY', 'Sweep', 'write_calibration_bag']

_START_NS = 1_700_000_000_000_000_000


@dataclass(frozen=True)
class Sweep:
    """What to record. Angles in rad, rates in Hz, times in s, noise sd in rad."""

    truth: dict[str, float]
    theta_range: tuple[float, float] = (-0.10471975511965978, 0.12217304763960307)
    duration: float = 60.0
    cycles: float = 2.0  #: down-and-up sweeps over the duration (a cosine)
    joint_rate: float = 100.0
    sensor_rate: float = 50.0
    sensor: str = 'float64'  #: 'float64' or 'imu'
    sensor_noise: float = 1e-3
    counts_per_rev: int = 4096  #: encoder counts per motor turn (0: not rounded)
    reducer_ratio: float = 500.0
    sensor_delay: float = 0.0013  #: the sensor's first reading after the encoder's (s)
    sensor_clock_offset: float = 0.0  #: how far the sensor's clock runs ahead of the encoder's (s)
    joint_name: str = 'rocker_ab_joint'
    names: tuple[str, ...] = field(default=('rocker_ab_joint',))
    driven: Driven = Driven.GAMMA
    branch: Branch = Branch.UPPER
    seed: int = 0
    #: The antenna's load as built (``load_calibration.LOAD_NAMES``: kg, m, m, N m, N m s/rad, efficiency): the joint
    #: states then carry the joint's velocity (rad/s) and the effort it takes (N m, ``effort_model``) plus noise.
    load: dict[str, float] | None = None
    effort_noise: float = 0.02
    #: A real sensor's faults: a Float64 sensor's readings multiplied by ``sensor_scale`` (-1: the sign flipped,
    #: 180/pi: degrees); an IMU rolled by ``imu_roll`` (rad) about its x axis, then yawed by ``imu_yaw`` (rad)
    #: about its z; ``glitches``: (reading index, rad added), NaN making the reading invalid (a Float64 NaN, an
    #: IMU's all-zero acceleration).
    sensor_scale: float = 1.0
    imu_roll: float = 0.0
    imu_yaw: float = 0.0
    glitches: tuple[tuple[int, float], ...] = ()
    #: The sensor's noise from one reading to the next, AR(1) with this lag-1 correlation (its sd sensor_noise).
    noise_correlation: float = 0.0
    #: Play between the encoder (on the motor) and the rocker (rad at the joint): the motor leads the rocker by half
    #: of it in the direction of motion.
    backlash: float = 0.0

    def linkage(self) -> AntennaLinkage:
        t = self.truth
        return AntennaLinkage(frame=t['frame_length'], rocker_ab=t['rocker_ab_length'], coupler=t['coupler_length'],
                              rocker_cd=t['rocker_cd_length'])

    def theta(self, seconds: np.ndarray) -> np.ndarray:
        """The true antenna angle (rad) at ``seconds`` from the start."""
        lo, hi = self.theta_range
        phase = 2.0 * math.pi * self.cycles * np.asarray(seconds) / self.duration
        return 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos(phase)

    def theta_rate(self, seconds: np.ndarray) -> np.ndarray:
        """d theta/dt (rad/s) at ``seconds``."""
        lo, hi = self.theta_range
        omega = 2.0 * math.pi * self.cycles / self.duration
        return np.asarray(-0.5 * (hi - lo) * omega * np.sin(omega * np.asarray(seconds)))

    def true_q(self, theta: np.ndarray) -> np.ndarray:
        """The true driven rocker angle (rad) at antenna angle ``theta`` (rad)."""
        g, d = self.linkage().rocker_angles(theta, self.branch)
        return np.asarray(g if self.driven is Driven.GAMMA else d)

    def measured_q(self, q_true: np.ndarray) -> np.ndarray:
        """The encoder's report of the driven joint (rad): its zero off by -driven_joint_offset, rounded to its
        counts."""
        q = q_true - self.truth['driven_joint_offset']
        if self.counts_per_rev:
            step = 2.0 * math.pi / (self.counts_per_rev * self.reducer_ratio)
            q = np.round(q / step) * step
        return q


def write_calibration_bag(path: str | os.PathLike[str], sweep: Sweep, joint_topic: str | None = None,
                          angle_topic: str = '/antenna_inclinometer', storage: Storage = DEFAULT_STORAGE) -> Path:
    """Write the recording ``sweep`` describes (joint states on joint_state_broadcaster's topic by default)."""
    missing = [n for n in PARAMETER_NAMES if n not in sweep.truth]
    if missing:
        raise ValueError(f'truth lacks {missing}')
    rng = np.random.default_rng(sweep.seed)
    tj = np.arange(0.0, sweep.duration, 1.0 / sweep.joint_rate)
    ts = np.arange(sweep.sensor_delay, sweep.duration, 1.0 / sweep.sensor_rate)
    qm = sweep.measured_q(sweep.true_q(sweep.theta(tj)) + 0.5 * sweep.backlash * np.sign(_q_rate(sweep, tj)))
    velocity, effort, has_velocity = _load(sweep, tj, rng)
    noise = rng.normal(0.0, sweep.sensor_noise, ts.size)
    if sweep.noise_correlation:
        rho, fresh = sweep.noise_correlation, math.sqrt(1.0 - sweep.noise_correlation ** 2)
        for i in range(1, noise.size):
            noise[i] = rho * noise[i - 1] + fresh * noise[i]
    reading = sweep.theta(ts) + sweep.truth['sensor_offset'] + noise
    for i, added in sweep.glitches:
        reading[i] = math.nan if math.isnan(added) else reading[i] + added
    j_ns = _START_NS + seconds_to_ns(tj)
    s_ns = _START_NS + seconds_to_ns(ts + sweep.sensor_clock_offset)
    k = len(sweep.names)
    position = np.zeros((tj.size, k))
    position[:, sweep.names.index(sweep.joint_name)] = qm
    i = sweep.names.index(sweep.joint_name)
    efforts, velocities = np.zeros((tj.size, k)), np.zeros((tj.size, k))
    efforts[:, i], velocities[:, i] = effort, velocity
    joint_raws = encode_joint_states(j_ns, '', sweep.names, position, efforts, velocities,
                                     np.full(tj.size, has_velocity))
    if sweep.sensor == 'imu':
        sensor_raws = _imus(s_ns, reading, sweep.imu_roll, sweep.imu_yaw)
        sensor_type = IMU
    elif sweep.sensor == 'float64':
        sensor_raws = encode_float64s(reading * sweep.sensor_scale)
        sensor_type = FLOAT64
    else:
        raise ValueError(f'sensor {sweep.sensor!r}: float64 or imu')
    # Receive times: the joint states a little after their stamps (the header stamp is what counts), the Float64
    # readings at their sampling time (they have no stamp: the receive time is all there is).
    j_log = j_ns + rng.integers(200_000, 2_000_000, tj.size)
    events = sorted([(int(t), 0, i) for i, t in enumerate(j_log)] + [(int(t), 1, i) for i, t in enumerate(s_ns)])
    with AtomicBagWriter(path, storage) as bag:
        jc = bag.add_topic(joint_topic or f'/{BROADCASTER_JOINT_STATES.name}', JOINT_STATE, [recorded_qos()])
        sc = bag.add_topic(angle_topic, sensor_type, [recorded_qos()])
        write = bag.write
        for log, which, i in events:
            if which == 0:
                write(jc, log, joint_raws[i])
            else:
                write(sc, log, sensor_raws[i])
    return Path(path)


def _q_rate(sweep: Sweep, t: np.ndarray) -> np.ndarray:
    """The true driven rocker's rate (rad/s) at ``t`` (s): the antenna's rate through the linkage's."""
    link = sweep.linkage()
    theta = sweep.theta(t)
    rates = link.rates_at(theta, *link.rocker_angles(theta, sweep.branch))
    return np.asarray(sweep.theta_rate(t) * np.asarray(rates.dgamma_dtheta if sweep.driven is Driven.GAMMA
                                                        else rates.ddelta_dtheta))


def _load(sweep: Sweep, tj: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, bool]:
    """(joint velocity rad/s, effort N m, whether the joint states carry a velocity) of the sweep's load."""
    if sweep.load is None:
        return np.zeros(tj.size), np.zeros(tj.size), False
    link = sweep.linkage()
    theta = sweep.theta(tj)
    q_rate = _q_rate(sweep, tj)
    q_true = sweep.true_q(theta)
    branch = inverse_branch(link, 0.5 * sum(sweep.theta_range), sweep.driven, sweep.branch)
    p = np.array([sweep.load[name] for name in LOAD_NAMES])
    pose = load_pose(link, q_true, q_rate, sweep.driven, branch)
    effort = effort_model(p, pose, GRAVITY)[0] + rng.normal(0.0, sweep.effort_noise, tj.size)
    return q_rate, effort, True


def _imus(stamps_ns: np.ndarray, theta: np.ndarray, roll: float = 0.0, yaw: float = 0.0) -> list[bytes]:
    """CDR Imu messages at rest on the antenna at ``theta`` (rad), rolled by ``roll`` (rad) about x, then yawed by
    ``yaw`` about its z: linear_acceleration = Rz(-yaw) g (-sin theta, cos theta sin roll, cos theta cos roll); all
    zero where theta is NaN."""
    store = jazzy_typestore()
    t = store.types
    msg = t[IMU](header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](sec=0, nanosec=0),
                                                 frame_id='antenna_imu'),
                 orientation=t['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0),
                 orientation_covariance=np.full(9, -1.0),
                 angular_velocity=t['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
                 angular_velocity_covariance=np.zeros(9),
                 linear_acceleration=t['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
                 linear_acceleration_covariance=np.zeros(9))
    template = bytes(store.serialize_cdr(msg, IMU))
    at = 16 + len('antenna_imu') + 1
    at += -(at - 4) % 8
    accel_at = at + 8 * (4 + 9 + 3 + 9)
    sec, nanosec = split_ns(stamps_ns)
    cy, sy = math.cos(yaw), math.sin(yaw)
    out = []
    for s, ns, th in zip(sec.tolist(), nanosec.tolist(), theta.tolist(), strict=True):
        raw = bytearray(template)
        struct.pack_into('<iI', raw, 4, s, ns)
        x, y, z = (-GRAVITY * math.sin(th), GRAVITY * math.cos(th) * math.sin(roll),
                   GRAVITY * math.cos(th) * math.cos(roll))
        accel = (0.0, 0.0, 0.0) if math.isnan(th) else (cy * x + sy * y, -sy * x + cy * y, z)
        struct.pack_into('<3d', raw, accel_at, *accel)
        out.append(bytes(raw))
    return out
