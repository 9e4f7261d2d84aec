#!/usr/bin/env python3
"""Writes a rosbag2 recording (MCAP storage) the way `ros2 bag record` lays it out, with
rosbags' own writer: reads a JSON request on stdin, {"path": DIR, "messages": [{"topic",
"type", "stamp_ns", "hex"}]} (payloads already CDR-encoded, written as they are), and
prints {"mcap": the .mcap file inside DIR}. node/tests/integration/node_rosbag.rs uses it
to make a robot-style recording no code of the project wrote."""

import json
import sys
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore


def main():
    request = json.load(sys.stdin)
    typestore = get_typestore(Stores.ROS2_JAZZY)
    path = Path(request['path'])
    connections = {}
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for m in request['messages']:
            topic = m['topic']
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, m['type'], typestore=typestore)
            writer.write(connections[topic], m['stamp_ns'], bytes.fromhex(m['hex']))
    mcap = next(path.glob('*.mcap'))
    print(json.dumps({'mcap': str(mcap)}))


if __name__ == '__main__':
    main()
