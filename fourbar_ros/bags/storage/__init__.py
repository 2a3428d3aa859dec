"""Bag storage with ``rosbags`` (no rclpy), mcap or sqlite3: the names the rest of the package imports."""

from fourbar_ros.bags.storage.common import (
    COMMAND_TOPIC,
    METADATA_VERSION,
    BagError,
    jazzy_typestore,
    recorded_qos,
    time_from_ns,
)
from fourbar_ros.bags.storage.read import (
    BagReader,
    CommandStream,
    find_topic,
    fingerprint,
    open_bag,
    read_commands,
    read_messages,
)
from fourbar_ros.bags.storage.reindex import ReindexResult, partial_dirs, reindex
from fourbar_ros.bags.storage.write import AtomicBagWriter, float64_cdr, write_command_bag
from fourbar_ros.interface.topics import (  # re-exported
    COMMANDS,
    DEFAULT_STORAGE,
    DIAGNOSTIC_ARRAY,
    FLOAT64,
    JOINT_STATE,
    MEASURED,
    TRAJECTORIES,
    Kind,
    Storage,
    sibling_topic,
)

__all__ = [
    'COMMANDS', 'COMMAND_TOPIC', 'DEFAULT_STORAGE', 'DIAGNOSTIC_ARRAY', 'FLOAT64', 'JOINT_STATE', 'MEASURED',
    'METADATA_VERSION', 'TRAJECTORIES', 'AtomicBagWriter', 'BagError', 'BagReader', 'CommandStream', 'Kind',
    'ReindexResult', 'Storage', 'find_topic', 'fingerprint', 'float64_cdr', 'jazzy_typestore', 'open_bag',
    'partial_dirs', 'read_commands', 'read_messages', 'recorded_qos', 'reindex', 'sibling_topic', 'time_from_ns',
    'write_command_bag',
]
