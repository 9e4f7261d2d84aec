#!/usr/bin/env python3
"""Real ROS 2 (rclpy, Jazzy, Fast DDS) nodes that talk to the StereoSplat node through the
zenoh ROS 2 bridge: node/tests/ros2_bridge.rs runs them. Run through scripts/ros2_env.sh.

    ros2_drive_node.py publish --mcap DRIVE.mcap --namespace NS [--robot] [--period S] [--match-timeout S]
    ros2_drive_node.py listen --namespace NS --bins N [--timeout S] [--match-timeout S]

`publish` (node `stereosplat_drive`): reads the node's input topics from an MCAP file (as
`stereosplat record` writes them: /NS/left/image, /NS/right/image, /NS/left/camera_info,
/NS/right/camera_info, /NS/pose), deserializes each payload into its rclpy message with
`deserialize_message`, waits until every publisher has a matched subscription (the bridge's
DDS reader) and prints `{"matched": true}`, then publishes them in log-time order, `--period`
seconds apart per frame (the camera infos first), and prints `{"published": {topic: count}}`.
With `--robot` the inputs are a robot's instead: JPEG sensor_msgs/CompressedImage on
/NS/left/image/compressed and /NS/right/image/compressed, the camera infos, the /tf and
/tf_static tree (tf2_msgs/TFMessage) and nav_msgs/Odometry on /NS/odometry (the static
transforms first with the camera infos).

`listen` (node `stereosplat_listener`): subscribes to /NS/bin/map (sensor_msgs/PointCloud2),
/NS/bin/pose (geometry_msgs/PoseStamped), /NS/latency (stereosplat_msgs/BinLatency) and
/NS/diagnostics (stereosplat_msgs/Diagnostics), waits until each subscription has a matched
publisher (the bridge's DDS writer: the bridge makes one only once it has discovered the
subscription, and a volatile subscription misses whatever was written before it matched),
prints `{"ready": true}`, and once N bin
poses arrived (or after `--timeout`, then a second more for stragglers) prints a JSON summary:
each map's frame_id, stamp, width, height, point_step and field names, each pose's frame_id,
stamp and position, the latencies' bin ids and the number of diagnostics messages.

Every publisher and subscription is reliable, volatile, keep last 100. Discovery stays on
the loopback interface through the Fast DDS profile of FASTRTPS_DEFAULT_PROFILES_FILE
(launch/fastdds_localhost.xml: UDPv4 on 127.0.0.1 only, no multicast).
"""

import argparse
import json
import sys
import time

import rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
from tf2_msgs.msg import TFMessage
from stereosplat_msgs.msg import BinLatency, Diagnostics

QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                 reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)

INPUTS = {
    'left/camera_info': CameraInfo, 'right/camera_info': CameraInfo,
    'left/image': Image, 'right/image': Image, 'pose': PoseStamped,
}

# A robot's graph: names under the namespace, or absolute (tf2's /tf and /tf_static).
ROBOT_INPUTS = {
    'left/camera_info': CameraInfo, 'right/camera_info': CameraInfo,
    'left/image/compressed': CompressedImage, 'right/image/compressed': CompressedImage,
    '/tf': TFMessage, '/tf_static': TFMessage, 'odometry': Odometry,
}


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def spin_until(node, done, timeout):
    """Spins `node` until `done()` or `timeout` seconds; whether `done()` held."""
    end = time.monotonic() + timeout
    while not done() and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    return done()


def publish(args):
    from mcap.reader import make_reader

    ns = args.namespace.strip('/')
    inputs = ROBOT_INPUTS if args.robot else INPUTS
    messages = []
    with open(args.mcap, 'rb') as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            topic = channel.topic
            if topic.startswith(f'/{ns}/'):
                topic = topic[len(ns) + 2:]
            if topic in inputs:
                messages.append((topic, deserialize_message(message.data, inputs[topic])))
    rclpy.init()
    node = rclpy.create_node('stereosplat_drive')
    name = lambda t: t if t.startswith('/') else f'/{ns}/{t}'
    # /tf_static latched, as tf2's static broadcaster publishes it.
    latched = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    qos = lambda t: latched if t == '/tf_static' else QOS
    pubs = {t: node.create_publisher(cls, name(t), qos(t)) for t, cls in inputs.items()}
    matched = spin_until(node, lambda: all(p.get_subscription_count() > 0 for p in pubs.values()),
                         args.match_timeout)
    if not matched:
        missing = [t for t, p in pubs.items() if p.get_subscription_count() == 0]
        sys.exit(f'no subscription matched {missing} within {args.match_timeout} s')
    print(json.dumps({'matched': True}), flush=True)
    counts = {}
    infos = [(t, m) for t, m in messages if t.endswith('camera_info')][:2]
    infos += [(t, m) for t, m in messages if t == '/tf_static']
    for topic, msg in infos:
        pubs[topic].publish(msg)
    spin_until(node, lambda: False, 1.0)
    frame_end = 'right/image/compressed' if args.robot else 'pose'
    for topic, msg in messages:
        pubs[topic].publish(msg)
        counts[topic] = counts.get(topic, 0) + 1
        if topic == frame_end:
            spin_until(node, lambda: False, args.period)
    spin_until(node, lambda: False, 1.0)
    print(json.dumps({'published': counts}), flush=True)
    node.destroy_node()
    rclpy.shutdown()


def listen(args):
    ns = args.namespace.strip('/')
    rclpy.init()
    node = rclpy.create_node('stereosplat_listener')
    got = {'maps': [], 'poses': [], 'latency_bins': [], 'diagnostics': 0}

    def on_map(m):
        got['maps'].append({
            'frame_id': m.header.frame_id, 'stamp_ns': stamp_ns(m.header), 'width': m.width,
            'height': m.height, 'point_step': m.point_step, 'bytes': len(m.data),
            'fields': [f.name for f in m.fields]})

    def on_pose(m):
        p = m.pose.position
        got['poses'].append({'frame_id': m.header.frame_id, 'stamp_ns': stamp_ns(m.header),
                             'position': [p.x, p.y, p.z]})

    def on_latency(m):
        got['latency_bins'].append(int(m.bin_id))

    def on_diagnostics(_m):
        got['diagnostics'] += 1

    subs = [
        node.create_subscription(PointCloud2, f'/{ns}/bin/map', on_map, QOS),
        node.create_subscription(PoseStamped, f'/{ns}/bin/pose', on_pose, QOS),
        node.create_subscription(BinLatency, f'/{ns}/latency', on_latency, QOS),
        node.create_subscription(Diagnostics, f'/{ns}/diagnostics', on_diagnostics, QOS),
    ]
    matched = spin_until(node, lambda: all(s.get_publisher_count() > 0 for s in subs),
                         args.match_timeout)
    if not matched:
        missing = [s.topic_name for s in subs if s.get_publisher_count() == 0]
        sys.exit(f'no publisher matched {missing} within {args.match_timeout} s')
    print(json.dumps({'ready': True}), flush=True)
    spin_until(node, lambda: len(got['poses']) >= args.bins, args.timeout)
    spin_until(node, lambda: False, 1.0)
    print(json.dumps(got), flush=True)
    del subs
    node.destroy_node()
    rclpy.shutdown()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    sub = parser.add_subparsers(dest='command', required=True)
    p = sub.add_parser('publish')
    p.add_argument('--mcap', required=True)
    p.add_argument('--namespace', default='stereosplat')
    p.add_argument('--robot', action='store_true')
    p.add_argument('--period', type=float, default=0.1)
    p.add_argument('--match-timeout', type=float, default=60.0)
    p = sub.add_parser('listen')
    p.add_argument('--namespace', default='stereosplat')
    p.add_argument('--bins', type=int, required=True)
    p.add_argument('--timeout', type=float, default=120.0)
    p.add_argument('--match-timeout', type=float, default=60.0)
    args = parser.parse_args()
    {'publish': publish, 'listen': listen}[args.command](args)


if __name__ == '__main__':
    main()
