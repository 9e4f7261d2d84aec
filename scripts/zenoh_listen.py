#!/usr/bin/env python3
"""Listen to a StereoSplat node over zenoh and decode what it publishes with rosbags.

Software no one here wrote on both layers: the Python `eclipse-zenoh` package receives the
samples, `rosbags` (ROS 2 Jazzy type store, plus the node's own messages registered from
node/src/msg/*.msg) deserializes the CDR. node/tests/integration/python_subscriber.rs runs it
beside an in-process node and compares what it saw with what a Rust subscriber saw.

    python3 scripts/zenoh_listen.py --connect tcp/127.0.0.1:7447 [--namespace NS | KEY ...]
                                    [--count N] [--timeout S] [--until-eof]

The zenoh session is a peer that connects to the endpoint only (multicast and gossip scouting
off). It subscribes to the given keys (zenoh key expressions), or `<namespace>/**`, `tf` and
`tf_static` (the transforms are absolute topics), once
connected, prints one line `{"ready": true}`, and stops after N samples (`--count`), after
S seconds (`--timeout`, default 60) or, with `--until-eof`, when stdin closes, whichever
comes first. Then it prints one JSON line, a summary per key:

    {"keys": {KEY: {"type": "sensor_msgs/msg/PointCloud2", "count": 3, "errors": [],
                    "messages": [...], ...aggregates...}}, "samples": 17, "stopped_by": "eof"}

Per message: PointCloud2 -> frame_id, stamp_ns, width, height, point_step, fields (names) and
first_point ({field: value}); PoseStamped -> frame_id, stamp_ns, position, orientation (and
position_bits, the IEEE-754 bits of each f64 as integers so a reader can compare exactly);
BinLatency -> every field; MapUpdate -> sequence, snapshot, bin_id, id counts, width;
Diagnostics -> stamp_ns and counters; Image -> frame_id, size, encoding; CameraInfo -> frame_id,
size, k. Aggregates per key: bin_ids (BinLatency), positions (PoseStamped), widths and fields
(PointCloud2), sequences (MapUpdate).

A key's type comes from its name: rmw_zenoh keys carry it (`pkg::msg::dds_::Name_`), plain
keys end in one of the node's topic names (`bin/map`, `latency`, ...; see docs/node.md,
"Topics"). Install the packages with `pip install -r scripts/requirements.txt`.
"""

import argparse
import json
import pathlib
import struct
import sys
import threading
import time

import zenoh
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

MSG_DIR = pathlib.Path(__file__).resolve().parent.parent / 'node' / 'src' / 'msg'
PACKAGE = 'stereosplat_msgs'

# Plain-mode topic names (docs/node.md, "Topics") -> message type.
TOPIC_TYPES = {
    'left/image': 'sensor_msgs/msg/Image',
    'right/image': 'sensor_msgs/msg/Image',
    'left/camera_info': 'sensor_msgs/msg/CameraInfo',
    'right/camera_info': 'sensor_msgs/msg/CameraInfo',
    'pose': 'geometry_msgs/msg/PoseStamped',
    'bin/map': 'sensor_msgs/msg/PointCloud2',
    'bin/pose': 'geometry_msgs/msg/PoseStamped',
    'bin/render': 'sensor_msgs/msg/Image',
    'map/bev': 'sensor_msgs/msg/Image',
    'map/update': f'{PACKAGE}/msg/MapUpdate',
    'latency': f'{PACKAGE}/msg/BinLatency',
    'diagnostics': f'{PACKAGE}/msg/Diagnostics',
    'tf': 'tf2_msgs/msg/TFMessage',
    'tf_static': 'tf2_msgs/msg/TFMessage',
}

# PointField datatype -> struct format character (little endian unless is_bigendian).
POINT_FORMATS = {1: 'b', 2: 'B', 3: 'h', 4: 'H', 5: 'i', 6: 'I', 7: 'f', 8: 'd'}


def typestore():
    """ROS 2 Jazzy's types plus the node's own, from the same .msg files the node hashes."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in sorted(MSG_DIR.glob('*.msg')):
        types.update(get_types_from_msg(path.read_text(), f'{PACKAGE}/msg/{path.stem}'))
    store.register(types)
    return store


def type_of(key):
    """The message type a key carries, or None when the key is not one of the node's."""
    for part in key.split('/'):
        if '::msg::dds_::' in part:
            pkg, name = part.split('::msg::dds_::')
            return f'{pkg}/msg/{name.rstrip("_")}'
    for topic, typename in TOPIC_TYPES.items():
        if key == topic or key.endswith('/' + topic):
            return typename
    return None


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def f64_bits(x):
    return struct.unpack('<Q', struct.pack('<d', x))[0]


def first_point(msg):
    """The first point's values by field name, read with struct from the declared layout."""
    if msg.width == 0 or msg.height == 0:
        return None
    data = bytes(msg.data)
    order = '>' if msg.is_bigendian else '<'
    point = {}
    for f in msg.fields:
        fmt = POINT_FORMATS.get(f.datatype)
        if fmt is None or f.count != 1:
            continue
        point[f.name] = struct.unpack_from(order + fmt, data, f.offset)[0]
    return point


def summarize(typename, msg):
    """A small JSON summary of one decoded message."""
    if typename == 'sensor_msgs/msg/PointCloud2':
        return {
            'frame_id': msg.header.frame_id, 'stamp_ns': stamp_ns(msg.header),
            'width': msg.width, 'height': msg.height, 'point_step': msg.point_step,
            'row_step': msg.row_step, 'is_dense': bool(msg.is_dense),
            'fields': [f.name for f in msg.fields], 'first_point': first_point(msg),
        }
    if typename == 'geometry_msgs/msg/PoseStamped':
        p, q = msg.pose.position, msg.pose.orientation
        return {
            'frame_id': msg.header.frame_id, 'stamp_ns': stamp_ns(msg.header),
            'position': [p.x, p.y, p.z], 'position_bits': [f64_bits(v) for v in (p.x, p.y, p.z)],
            'orientation': [q.x, q.y, q.z, q.w],
        }
    if typename == f'{PACKAGE}/msg/BinLatency':
        fields = {name: int(getattr(msg, name)) for name in (
            'bin_id', 'first_frame_arrival_ns', 'bin_close_ns', 'model_start_ns',
            'model_end_ns', 'render_end_ns', 'publish_ns', 'queue_depth', 'drops',
            'bad_messages', 'check_verdict', 'check_action', 'fallback_verdict',
            'check_samples', 'base_end_ns', 'pseudo_render_end_ns', 'enhance_end_ns',
            'plus_end_ns', 'fuse_end_ns', 'map_fused_ns')}
        fields.update({name: float(getattr(msg, name))
                       for name in ('check_score', 'fallback_score')})
        fields['operating_point'] = str(msg.operating_point)
        return fields
    if typename == f'{PACKAGE}/msg/MapUpdate':
        return {
            'frame_id': msg.header.frame_id, 'sequence': int(msg.sequence),
            'snapshot': bool(msg.snapshot), 'bin_id': int(msg.bin_id),
            'ids': len(msg.ids), 'source_bins': len(msg.source_bins),
            'removed_ids': len(msg.removed_ids), 'width': msg.gaussians.width,
            'fields': [f.name for f in msg.gaussians.fields],
        }
    if typename == f'{PACKAGE}/msg/Diagnostics':
        return {'stamp_ns': int(msg.stamp_ns),
                'counters': {c.kind: int(c.count) for c in msg.counters}}
    if typename == 'sensor_msgs/msg/Image':
        return {'frame_id': msg.header.frame_id, 'stamp_ns': stamp_ns(msg.header),
                'width': msg.width, 'height': msg.height, 'encoding': msg.encoding,
                'step': msg.step, 'bytes': len(msg.data)}
    if typename == 'tf2_msgs/msg/TFMessage':
        return {'transforms': [
            {'frame_id': t.header.frame_id, 'child_frame_id': t.child_frame_id,
             'stamp_ns': stamp_ns(t.header),
             'translation': [t.transform.translation.x, t.transform.translation.y,
                             t.transform.translation.z]}
            for t in msg.transforms]}
    if typename == 'sensor_msgs/msg/CameraInfo':
        return {'frame_id': msg.header.frame_id, 'width': msg.width, 'height': msg.height,
                'k': [float(v) for v in msg.k]}
    return {}


def aggregate(typename, messages):
    """Per-key lists a reader compares directly."""
    if typename == 'sensor_msgs/msg/PointCloud2':
        return {'widths': [m['width'] for m in messages],
                'fields': messages[0]['fields'] if messages else [],
                'point_step': messages[0]['point_step'] if messages else 0}
    if typename == 'geometry_msgs/msg/PoseStamped':
        return {'positions': [m['position'] for m in messages]}
    if typename == f'{PACKAGE}/msg/BinLatency':
        return {'bin_ids': [m['bin_id'] for m in messages]}
    if typename == f'{PACKAGE}/msg/MapUpdate':
        return {'sequences': [m['sequence'] for m in messages],
                'id_counts': [m['ids'] for m in messages]}
    return {}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('keys', nargs='*', help='key expressions (default: <namespace>/**)')
    parser.add_argument('--connect', required=True, help='zenoh endpoint, e.g. tcp/127.0.0.1:7447')
    parser.add_argument('--namespace', default='stereosplat')
    parser.add_argument('--count', type=int, default=0, help='stop after this many samples')
    parser.add_argument('--timeout', type=float, default=60.0, help='stop after this many s')
    parser.add_argument('--until-eof', action='store_true', help='stop when stdin closes')
    args = parser.parse_args()

    store = typestore()
    lock = threading.Lock()
    done = threading.Event()
    raw = []  # (key, payload bytes) in arrival order; decoded after the session closes

    def on_sample(sample):
        with lock:
            raw.append((str(sample.key_expr), sample.payload.to_bytes()))
            if args.count and len(raw) >= args.count:
                done.set()

    config = zenoh.Config()
    config.insert_json5('mode', '"peer"')
    config.insert_json5('connect/endpoints', json.dumps([args.connect]))
    config.insert_json5('listen/endpoints', '[]')
    config.insert_json5('scouting/multicast/enabled', 'false')
    config.insert_json5('scouting/gossip/enabled', 'false')
    session = zenoh.open(config)
    # Subscribe once the peer is connected, so the subscriptions reach it at once.
    deadline = time.monotonic() + 10.0
    while not list(session.info.peers_zid()) and time.monotonic() < deadline:
        time.sleep(0.05)
    keys = args.keys or [f'{args.namespace.strip("/")}/**', 'tf', 'tf_static']
    subscribers = [session.declare_subscriber(k, on_sample) for k in keys]
    print(json.dumps({'ready': True, 'keys': keys}), flush=True)

    stopped_by = ['timeout']
    if args.until_eof:
        def wait_eof():
            sys.stdin.read()
            stopped_by[0] = 'eof'
            done.set()
        threading.Thread(target=wait_eof, daemon=True).start()
    if done.wait(args.timeout) and stopped_by[0] != 'eof':
        stopped_by[0] = 'count'
    for s in subscribers:
        s.undeclare()
    session.close()

    with lock:
        samples = list(raw)
    per_key = {}
    for key, payload in samples:
        entry = per_key.setdefault(key, {'type': type_of(key), 'count': 0, 'errors': [],
                                         'messages': []})
        entry['count'] += 1
        if entry['type'] is None:
            continue
        try:
            msg = store.deserialize_cdr(payload, entry['type'])
            entry['messages'].append(summarize(entry['type'], msg))
        except Exception as e:  # a decode failure is reported, not fatal
            entry['errors'].append(f'{type(e).__name__}: {e}')
    for entry in per_key.values():
        entry.update(aggregate(entry['type'], entry['messages']))
    print(json.dumps({'keys': per_key, 'samples': len(samples), 'stopped_by': stopped_by[0]}),
          flush=True)


if __name__ == '__main__':
    main()
