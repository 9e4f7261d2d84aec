#!/usr/bin/env python3
"""Decode and encode ROS 2 CDR messages with rosbags, an independent CDR implementation.

The node's interop test (node/tests/integration/msg_interop.rs) uses it to check that what the node
writes is what a ROS 2 reader sees, and the reverse. One JSON request on stdin, one JSON
reply on stdout:

    {"msgs": {"pkg/msg/Type": ".msg text", ...},      # extra definitions to register
     "decode": [{"type": "sensor_msgs/msg/Image", "hex": "000100..."}, ...],
     "encode": [{"type": "...", "value": {...}, "little_endian": true}, ...],
     "hash": ["sensor_msgs/msg/Image", ...]}

    {"decoded": [{field: value, ...}, ...], "encoded": ["hex", ...], "hashes": {type: hash}}

Decoded messages are nested JSON objects; arrays become lists of numbers. A decoded
sensor_msgs/msg/PointCloud2 also gets "points": {field name: [values]}, read from `data`
with numpy using the message's own PointField layout. Types come from rosbags' ROS 2 Jazzy
store. Install with `pip install -r scripts/requirements.txt`.
"""

import json
import sys

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

# PointField datatype -> numpy scalar type (little endian; byte-swapped when is_bigendian).
POINT_DTYPES = {1: 'i1', 2: 'u1', 3: '<i2', 4: '<u2', 5: '<i4', 6: '<u4', 7: '<f4', 8: '<f8'}

# .msg base type -> numpy dtype of its arrays.
ARRAY_DTYPES = {
    'bool': np.bool_, 'byte': np.uint8, 'char': np.uint8, 'int8': np.int8, 'uint8': np.uint8,
    'int16': np.int16, 'uint16': np.uint16, 'int32': np.int32, 'uint32': np.uint32,
    'int64': np.int64, 'uint64': np.uint64, 'float32': np.float32, 'float64': np.float64,
}


def to_json(store, value):
    """A decoded rosbags message (dataclass tree) as plain JSON values, message fields only
    (rosbags' classes also carry the constants and `__msgtype__`)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [to_json(store, v) for v in value]
    if hasattr(value, '__msgtype__'):
        _, fields = store.fielddefs[value.__msgtype__]
        return {name: to_json(store, getattr(value, name)) for name, _ in fields}
    return value


def cloud_points(msg):
    """The points of a PointCloud2, per field, read with numpy from the declared layout."""
    order = '>' if msg.is_bigendian else '<'
    names, formats, offsets = [], [], []
    for f in msg.fields:
        if f.datatype in POINT_DTYPES and f.count == 1:
            names.append(f.name)
            formats.append(POINT_DTYPES[f.datatype].replace('<', order))
            offsets.append(f.offset)
    dtype = np.dtype({'names': names, 'formats': formats, 'offsets': offsets,
                      'itemsize': msg.point_step})
    data = np.asarray(msg.data, dtype=np.uint8).tobytes()
    points = []
    for row in range(msg.height):
        start = row * msg.row_step
        points.append(np.frombuffer(data, dtype=dtype, count=msg.width, offset=start))
    allp = np.concatenate(points) if points else np.zeros(0, dtype=dtype)
    return {name: allp[name].astype(np.float64).tolist() for name in names}


def build(store, typename, value):
    """A rosbags message of `typename` from plain JSON values."""
    cls = store.types[typename]
    _, fields = store.fielddefs[typename]
    args = {}
    for name, (kind, desc) in fields:
        v = value[name]
        if kind == Nodetype.NAME:
            args[name] = build(store, desc, v)
        elif kind == Nodetype.BASE:
            args[name] = v
        else:
            (inner_kind, inner), _size = desc
            if inner_kind == Nodetype.NAME:
                args[name] = [build(store, inner, x) for x in v]
            elif inner[0] == 'string':
                args[name] = list(v)
            else:
                args[name] = np.array(v, dtype=ARRAY_DTYPES[inner[0]])
    return cls(**args)


def main():
    request = json.load(sys.stdin)
    store = get_typestore(Stores.ROS2_JAZZY)
    for typename, text in request.get('msgs', {}).items():
        store.register(get_types_from_msg(text, typename))
    reply = {'decoded': [], 'encoded': [], 'hashes': {}}
    for item in request.get('decode', []):
        msg = store.deserialize_cdr(bytes.fromhex(item['hex']), item['type'])
        out = to_json(store, msg)
        if item['type'] == 'sensor_msgs/msg/PointCloud2':
            out['points'] = cloud_points(msg)
        reply['decoded'].append(out)
    for item in request.get('encode', []):
        msg = build(store, item['type'], item['value'])
        raw = store.serialize_cdr(msg, item['type'], little_endian=item.get('little_endian', True))
        reply['encoded'].append(bytes(raw).hex())
    for typename in request.get('hash', []):
        reply['hashes'][typename] = store.hash_rihs01(typename)
    json.dump(reply, sys.stdout)


if __name__ == '__main__':
    main()
