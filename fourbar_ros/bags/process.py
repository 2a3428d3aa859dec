"""The bag fourbar_node would publish for a command bag, computed without the middleware (no rclpy).

The node's rules (``fourbar_ros.rules``) on blocks of ``BLOCK`` commands at their log times, written next to the
command topic, atomically. What is written: docs/how-to/bags.md."""

from __future__ import annotations

import os
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from itertools import islice

import numpy as np
import numpy.typing as npt

from fourbar_ros.bags.storage import (
    COMMANDS,
    FLOAT64,
    JOINT_STATE,
    AtomicBagWriter,
    BagError,
    BagReader,
    Storage,
    jazzy_typestore,
    open_bag,
    recorded_qos,
)
from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.cdr import decode_float64s, encode_float64s, encode_joint_states
from fourbar_ros.interface.topics import PER_COMMAND_OUTPUTS, sibling_topic
from fourbar_ros.rules.outputs import outputs_block
from fourbar_ros.rules.policy import Outcome, Policy, serve
from fourbar_ros.rules.velocity import IntArray, VelocityState

FloatArray = npt.NDArray[np.float64]

#: Commands per block: big enough that numpy's per-call cost vanishes, small enough for a few MB per block.
BLOCK = 65536


@dataclass
class ProcessStats:
    """Counts of a run, named like the node's diagnostics counters."""

    commands: int = 0
    accepted: int = 0
    clamped: int = 0
    rejected: dict[str, int] = field(default_factory=lambda: {o.value: 0 for o in Outcome if o.rejected})
    not_solved: int = 0
    published: int = 0
    with_velocity: int = 0
    seconds: float = 0.0
    topics: tuple[str, str] = ('', '')

    def count(self, outcomes: Counter[Outcome]) -> None:
        """Add a block's outcomes."""
        for outcome, n in outcomes.items():
            self.commands += n
            if outcome is Outcome.ACCEPTED:
                self.accepted += n
            elif outcome is Outcome.CLAMPED:
                self.clamped += n
            else:
                self.rejected[outcome.value] += n

    def summary(self) -> str:
        """One line for the user."""
        rejected = ', '.join(f'{v} {k.removeprefix("rejected_").replace("_", " ")}'
                             for k, v in self.rejected.items() if v)
        return (f'{self.commands} commands -> {self.published} joint_states and input_torque '
                f'({self.accepted} accepted, {self.clamped} clamped, {sum(self.rejected.values())} rejected'
                f'{": " + rejected if rejected else ""}'
                f'{f", {self.not_solved} not solvable" if self.not_solved else ""}) in {self.seconds:.2f} s')


# --------------------------------------------------------------------------- reading and writing

def _command_blocks(bag: BagReader, topic: str, block: int) -> Iterator[tuple[IntArray, FloatArray]]:
    """(log times ns, values rad) of the commands, ``block`` at a time."""
    messages = bag.messages([topic])
    while chunk := list(islice(messages, block)):
        yield _block(bag, topic, [m[1] for m in chunk], [m[2] for m in chunk])


def _block(bag: BagReader, topic: str, stamps: list[int], raws: list[bytes]) -> tuple[IntArray, FloatArray]:
    """(log times ns, values rad) of one block of raw commands."""
    values = decode_float64s(raws)
    if values is None:  # not the plain little-endian form: the full deserializer, message by message
        store, values = jazzy_typestore(), np.empty(len(raws))
        for j, raw in enumerate(raws):
            try:
                values[j] = float(store.deserialize_cdr(bytes(raw), FLOAT64).data)  # type: ignore[attr-defined]
            except Exception as exc:
                raise BagError(f'{bag.path}: message {bag.count - len(raws) + j} on {topic} is not a valid '
                               f'{FLOAT64} ({one_line(exc)})') from exc
    return np.array(stamps, dtype=np.int64), values


def process_bag(src: str | os.PathLike[str] | BagReader, dst: str | os.PathLike[str], cfg: AntennaConfig,
                topic: str | None = None, storage: Storage | None = None, block: int = BLOCK,
                on_block: Callable[[int], None] | None = None) -> ProcessStats:
    """Write to ``dst`` the joint_states and input_torque fourbar_node would publish for the commands of
    ``src`` (a path or an open bag; see the module docstring). ``topic``: the command topic (default:
    ``find_topic``'s ``/antenna_angle_cmd``); ``storage``: the output's (default: the input's). ``on_block(n)`` is
    called with the number of commands done after each block. Raises BagError (one line) for bad input;
    ``dst`` then does not appear.
    """
    start = time.perf_counter()
    stats = ProcessStats()
    names = cfg.joint_names
    policy, reach = Policy(cfg.out_of_limits), cfg.linkage.reach()
    anchor = VelocityState()
    with open_bag(src) as reader:
        chosen = reader.find(COMMANDS, topic)
        joint_topic, torque_topic = (sibling_topic(chosen, t.name) for t in PER_COMMAND_OUTPUTS)
        stats.topics = (joint_topic, torque_topic)
        with AtomicBagWriter(dst, storage or reader.storage) as bag:
            qos = [recorded_qos()]  # the node's publishers: reliable, volatile
            js_conn = bag.add_topic(joint_topic, JOINT_STATE, qos)
            tq_conn = bag.add_topic(torque_topic, FLOAT64, qos)
            for stamps, values in _command_blocks(reader, chosen, block):
                served = serve(values, cfg.theta_min, cfg.theta_max, policy, reach)
                stats.count(served.outcomes)
                out = outputs_block(cfg, served.theta, stamps[served.index], anchor)
                stats.not_solved += out.not_solved
                try:
                    js = encode_joint_states(out.stamps_ns, '', names, out.positions, out.efforts, out.velocities,
                                             out.has_velocity)
                except ValueError as exc:
                    raise BagError(f'{reader.path}: {exc}') from None
                bag.write_rows(out.stamps_ns.tolist(), ((js_conn, js), (tq_conn, encode_float64s(out.input_torque))))
                stats.published += out.stamps_ns.size
                stats.with_velocity += int(np.count_nonzero(out.has_velocity))
                if on_block is not None:
                    on_block(stats.commands)
            if stats.commands == 0:
                raise BagError(f'{reader.path}: topic {chosen} has no messages')
    stats.seconds = time.perf_counter() - start
    return stats
