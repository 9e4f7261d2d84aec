#!/usr/bin/env python3
"""Serialize and deserialize messages with the real ROS 2 Jazzy typesupport (rclpy), and
read type hashes from the type descriptions ROS 2 packages install.

The node's test node/tests/integration/msg_rclpy.rs drives it: what the node encodes, rclpy's
`deserialize_message` reads to the same field values; what rclpy's `serialize_message`
writes from those values, the test compares byte for byte with the node's bytes and decodes
in Rust. One JSON request on stdin, one JSON reply on stdout:

    {"decode": [{"type": "sensor_msgs/msg/Image", "hex": "000100..."}, ...],
     "encode": [{"type": "...", "value": {...}}, ...],
     "installed_hashes": ["sensor_msgs/msg/Image", ...]}

    {"decoded": [{field: value, ...}, ...], "encoded": ["hex", ...],
     "installed_hashes": {type: hash}}

Hashes come from `share/<pkg>/msg/<Type>.json` under the prefixes of AMENT_PREFIX_PATH,
which rosidl_generator_type_description writes when a package is built: the wheels' for the
standard types, scripts/ros2_msgs.sh's for tf2_msgs and stereosplat_msgs.

Run it through scripts/ros2_env.sh (the wheels of scripts/requirements.txt and the packages
of scripts/ros2_msgs.sh on the paths); rclpy's serialization needs no `rclpy.init()`.
"""

import array
import importlib
import os
import json
import sys
from pathlib import Path

from rclpy.serialization import deserialize_message, serialize_message

# Where installed packages keep their `share/` folders: the ament index's prefixes.
PREFIXES = [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', sys.prefix).split(':') if p]


def message_class(type_name):
    """The Python class of `pkg/msg/Type`."""
    pkg, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


def to_json(value):
    """A deserialized rclpy message as plain JSON values, message fields only."""
    if hasattr(value, 'get_fields_and_field_types'):
        return {name: to_json(getattr(value, name))
                for name in value.get_fields_and_field_types()}
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if isinstance(value, (list, tuple, array.array)) or type(value).__name__ == 'ndarray':
        return [to_json(v) for v in value]
    return value


def build(cls, value):
    """An rclpy message of class `cls` from plain JSON values."""
    msg = cls()
    for name, ftype in cls.get_fields_and_field_types().items():
        v = value[name]
        current = getattr(msg, name)
        if hasattr(current, 'get_fields_and_field_types'):
            setattr(msg, name, build(type(current), v))
        elif ftype.startswith('sequence<') and '/' in ftype:
            inner = ftype[len('sequence<'):-1]
            setattr(msg, name, [build(message_class(inner.replace('/', '/msg/', 1)), x)
                                for x in v])
        elif ftype in ('sequence<uint8>', 'sequence<octet>'):
            setattr(msg, name, bytes(v))
        else:
            setattr(msg, name, v)
    return msg


def installed_hash(type_name):
    """The RIHS01 hash the installed package's type description names for its own type."""
    pkg, _, name = type_name.split('/')
    path = next(p / 'share' / pkg / 'msg' / f'{name}.json' for p in PREFIXES
                if (p / 'share' / pkg / 'msg' / f'{name}.json').exists())
    description = json.loads(path.read_text())
    hashes = {h['type_name']: h['hash_string'] for h in description['type_hashes']}
    return hashes[type_name]


def main():
    request = json.load(sys.stdin)
    reply = {'decoded': [], 'encoded': [], 'installed_hashes': {}}
    for item in request.get('decode', []):
        msg = deserialize_message(bytes.fromhex(item['hex']), message_class(item['type']))
        reply['decoded'].append(to_json(msg))
    for item in request.get('encode', []):
        msg = build(message_class(item['type']), item['value'])
        reply['encoded'].append(serialize_message(msg).hex())
    for type_name in request.get('installed_hashes', []):
        reply['installed_hashes'][type_name] = installed_hash(type_name)
    json.dump(reply, sys.stdout)


if __name__ == '__main__':
    main()
