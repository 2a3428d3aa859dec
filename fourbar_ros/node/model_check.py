"""The actuator modes' live check of the model: an antenna angle sensor against the completed angle.

Composed by fourbar_node when ``antenna_sensor_type`` is not ``none``; what is compared and when a reading is
skipped: ``fourbar_ros.rules.model_check``; how readings are timed: docs/reference/topics.md. In the actuator modes a
mismatch that stays beyond ``slip_stop_mismatch`` stops the motion (``SlipStop``, ``on_slip``)."""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.interface.stamps import to_ns
from fourbar_ros.interface.topics import ANTENNA_SENSORS, Topic
from fourbar_ros.rules.diagnostics import Level
from fourbar_ros.rules.model_check import ModelCheck, SensorSkipped, SlipEvent, SlipReading, SlipStop, imu_theta
from fourbar_ros.runtime.problem_log import ProblemLog


class LiveModelCheck:
    """The sensor's subscription and the model check's diagnostics."""

    def __init__(self, node: Node, cfg: AntennaConfig, config: Callable[[], AntennaConfig],
                 qos: Callable[[Topic], QoSProfile], problems: ProblemLog,
                 on_slip: Callable[[SlipEvent, str], None] | None = None) -> None:
        """``cfg``: the configuration the completion was built with (its geometry); ``config``: the running one
        (the sensor's offset, the thresholds, the window); ``qos``: the profile of a topic; ``on_slip``: told each
        event of the slip stop with its line (why it stopped; '' when cleared)."""
        self.check = ModelCheck(cfg)
        self.slip = SlipStop()
        self._on_slip = on_slip
        self._config = config
        self._problems = problems
        self._clock = node.get_clock()
        self.sensor_type = cfg.antenna_sensor_type
        topic = ANTENNA_SENSORS[self.sensor_type]
        if self.sensor_type == 'imu':
            self._sub = node.create_subscription(Imu, topic.name, problems.guard.wrap(f'sub_{topic.name}', self.on_imu),
                                                 qos(topic))
        else:
            self._sub = node.create_subscription(Float64, topic.name,
                                                 problems.guard.wrap(f'sub_{topic.name}', self.on_float64), qos(topic))

    def _now_ns(self) -> int:
        ns: int = self._clock.now().nanoseconds
        return ns

    def on_completed(self, stamp_ns: int, q: float) -> None:
        """A completed measurement of the driven joint (rad) and its header stamp (ns; 0: none)."""
        self.check.note_measured(stamp_ns if stamp_ns else self._now_ns(), q)

    def on_float64(self, msg: Float64) -> None:
        self._compare(self._now_ns(), float(msg.data))

    def on_imu(self, msg: Imu) -> None:
        stamp = to_ns(msg.header.stamp)
        a = msg.linear_acceleration
        theta = imu_theta(float(a.x), float(a.y), float(a.z), self._config().antenna_imu_yaw)
        self._compare(stamp if stamp else self._now_ns(), theta)

    def _compare(self, stamp_ns: int, theta: float | SensorSkipped) -> None:
        cfg = self._config()
        outcome = self.check.compare(cfg, stamp_ns, theta, time.monotonic())
        if isinstance(outcome, SensorSkipped):
            shown = f' ({theta!r} rad)' if isinstance(theta, float) else ''
            self._problems.warn(f'antenna sensor {outcome.value}', f'antenna_angle_sensor reading at {stamp_ns} ns'
                                f'{shown} skipped: {outcome.value.replace("_", " ")}')
            return
        assert isinstance(theta, float)
        event = self.slip.update(cfg, SlipReading(stamp_ns, outcome, theta - cfg.antenna_sensor_offset))
        if event is not None and self._on_slip is not None:
            self._on_slip(event, self.slip.stopped)

    def diagnostics(self) -> tuple[Level, str, list[tuple[str, str]]]:
        """(level, message, key/value pairs) of the check: WARN or ERROR from the mismatch's window
        (``ModelCheck.diagnostics``); ERROR while the slip stop holds the drive."""
        level, message, values = self.check.diagnostics(self._config(), time.monotonic())
        values += self.slip.values()
        if self.slip.stopped:
            level, message = 2, (f'motion stopped: {self.slip.stopped}; commands are dropped until the sensor agrees '
                                 'with the model again (re-home the drive, or slip_stop_mismatch 0 to go on)')
        return Level(level), message, [('antenna_sensor_type', self.sensor_type), *values]
