#!/usr/bin/env python3
"""Read `x y z rgb` from the node's PointCloud2 bytes the way a ROS 2 Python node does.

node/tests/integration/msg_rgb.rs drives it: rclpy's `deserialize_message` (the ROS 2 Jazzy
typesupport of the `ros-jazzy-*` wheels) turns the node's CDR bytes into a
`sensor_msgs.msg.PointCloud2`, and `read_points` of the `pointcloud2` package (a standalone
port of ROS 2's `sensor_msgs_py.point_cloud2`, which has no wheel) reads the named fields into
a numpy structured array. `rgb` is then unpacked as the PCL/ROS convention says: the FLOAT32's
bits viewed as a little-endian uint32 `0x00RRGGBB`. One JSON request on stdin, one reply:

    {"clouds": ["hex", ...]}  ->  {"points": [[[x, y, z, r, g, b], ...], ...],
                                   "fields": [[name, ...], ...], "point_step": [n, ...]}

Run it through scripts/ros2_env.sh.
"""

import json
import sys

import numpy as np
from pointcloud2 import read_points
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2


def main():
    request = json.load(sys.stdin)
    reply = {'points': [], 'fields': [], 'point_step': []}
    for hex_bytes in request['clouds']:
        msg = deserialize_message(bytes.fromhex(hex_bytes), PointCloud2)
        points = read_points(msg, field_names=['x', 'y', 'z', 'rgb'])
        rgb = np.ascontiguousarray(points['rgb']).view(np.uint32)
        r, g, b = (rgb >> 16) & 0xff, (rgb >> 8) & 0xff, rgb & 0xff
        reply['points'].append([
            [float(p['x']), float(p['y']), float(p['z']), int(r[i]), int(g[i]), int(b[i])]
            for i, p in enumerate(points)
        ])
        reply['fields'].append([f.name for f in msg.fields])
        reply['point_step'].append(msg.point_step)
    json.dump(reply, sys.stdout)


if __name__ == '__main__':
    main()
