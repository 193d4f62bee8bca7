"""Record ROS 2 topics to an MCAP file that Foxglove and ``ros2 bag`` can open.

Messages are written as received (CDR bytes, ``raw=True`` subscriptions); each schema is
the ``ros2msg`` text of the type with its dependencies appended, the layout rosbag2 writes.
The message definitions come from the ``.msg`` files installed under ``share/`` of each
interface package (found through the ament index).
"""
import os
import re
import time

from mcap.writer import CompressionType, Writer

_BUILTIN = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
            'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'}
_SEPARATOR = '=' * 80 + '\n'


def _msg_file(type_name):
    from ament_index_python.packages import get_package_share_directory

    package, name = type_name.split('/msg/') if '/msg/' in type_name else type_name.split('/')
    return os.path.join(get_package_share_directory(package), 'msg', name + '.msg'), package


def _dependencies(text, package):
    deps = []
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        field_type = re.sub(r'(\[.*\]|<=\d+)$', '', line.split()[0])
        field_type = re.sub(r'<=\d+', '', field_type)
        if field_type in _BUILTIN:
            continue
        if field_type == 'Header':
            field_type = 'std_msgs/Header'
        deps.append(field_type if '/' in field_type else f'{package}/{field_type}')
    return deps


def message_definition(type_name):
    """Full ``ros2msg`` definition of ``pkg/msg/Type`` (or ``pkg/Type``) with dependencies."""
    path, package = _msg_file(type_name)
    with open(path) as handle:
        root = handle.read()
    parts, seen = [root], set()
    queue = _dependencies(root, package)
    while queue:
        dep = queue.pop(0)
        dep_pkg, dep_name = dep.replace('/msg/', '/').split('/')
        key = f'{dep_pkg}/msg/{dep_name}'
        if key in seen:
            continue
        seen.add(key)
        dep_path, _ = _msg_file(key)
        with open(dep_path) as handle:
            text = handle.read()
        parts.append(f'{_SEPARATOR}MSG: {dep_pkg}/{dep_name}\n{text}')
        queue.extend(_dependencies(text, dep_pkg))
    return '\n'.join(parts)


def type_name_of(msg_class):
    module = msg_class.__module__.split('.')  # e.g. nav_msgs.msg._odometry
    return f'{module[0]}/msg/{msg_class.__name__}'


class McapRecorder:
    """Subscribe to topics on ``node`` and write every message to ``path``."""

    def __init__(self, node, path, topics, qos_for=None):
        self.path = path
        self._handle = open(path, 'wb')  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._handle, compression=CompressionType.ZSTD)
        self._writer.start(profile='ros2', library='sela_ros')
        self._channels = {}
        self._sequence = 0
        self.counts = {}
        self._subs = []
        for topic, msg_class in topics.items():
            type_name = type_name_of(msg_class)
            schema_id = self._writer.register_schema(
                name=type_name, encoding='ros2msg',
                data=message_definition(type_name).encode())
            channel_id = self._writer.register_channel(topic=topic, message_encoding='cdr',
                                                       schema_id=schema_id)
            self._channels[topic] = channel_id
            self.counts[topic] = 0
            qos = qos_for(topic) if qos_for else 10
            self._subs.append(node.create_subscription(
                msg_class, topic, lambda data, t=topic: self._write(t, data), qos, raw=True))

    def _write(self, topic, data):
        if self._writer is None:
            return
        now = time.time_ns()
        self._sequence += 1
        self._writer.add_message(channel_id=self._channels[topic], log_time=now, data=data,
                                 publish_time=now, sequence=self._sequence)
        self.counts[topic] += 1

    def close(self):
        if self._writer is not None:
            self._writer.finish()
            self._writer = None
            self._handle.close()
