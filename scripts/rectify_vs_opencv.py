#!/usr/bin/env python3
"""Rectification maps and rectified images from OpenCV, for comparison with the node's.

The node's test node/tests/integration/rectify_opencv.rs runs it. One JSON request on stdin
(or in the file named as the first argument), one JSON reply on stdout:

    {"cameras": [{"name": "left", "width": 1408, "height": 376,
                  "distortion_model": "plumb_bob", "d": [...], "k": [9 row major],
                  "r": [9], "p": [12],
                  "raw": "/path/raw.rgb",         # width*height*3 bytes, packed RGB
                  "out": "/path/prefix"}, ...]}

    {"opencv": "5.0.0", "cameras": [{"name": "left", "map_x": "/path/prefix.map_x.f32",
                                     "map_y": "...", "rectified": "/path/prefix.rgb"}]}

For each camera it writes `<out>.map_x.f32` and `<out>.map_y.f32` (little-endian float32,
row major, the raw-image coordinate each rectified pixel samples) from
`cv2.initUndistortRectifyMap` (`cv2.fisheye.initUndistortRectifyMap` for `equidistant`) at
the camera's own size, as ROS's image_geometry calls them (K, D, R and P's left 3x3), and
`<out>.rgb`, the raw image through `cv2.remap` with INTER_LINEAR and BORDER_CONSTANT 0.
Install with `pip install -r scripts/requirements.txt`.
"""

import json
import sys

import cv2
import numpy as np


def rectify(camera):
    """Writes one camera's maps and rectified image; returns where they are."""
    w, h = camera['width'], camera['height']
    k = np.array(camera['k'], dtype=np.float64).reshape(3, 3)
    d = np.array(camera['d'], dtype=np.float64)
    r = np.array(camera['r'], dtype=np.float64).reshape(3, 3)
    p = np.array(camera['p'], dtype=np.float64).reshape(3, 4)[:, :3]
    if camera['distortion_model'] == 'equidistant':
        map_x, map_y = cv2.fisheye.initUndistortRectifyMap(k, d, r, p, (w, h), cv2.CV_32FC1)
    else:
        map_x, map_y = cv2.initUndistortRectifyMap(k, d, r, p, (w, h), cv2.CV_32FC1)
    raw = np.fromfile(camera['raw'], dtype=np.uint8).reshape(h, w, 3)
    rectified = cv2.remap(raw, map_x, map_y, cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    out = camera['out']
    files = {'map_x': out + '.map_x.f32', 'map_y': out + '.map_y.f32', 'rectified': out + '.rgb'}
    map_x.astype('<f4').tofile(files['map_x'])
    map_y.astype('<f4').tofile(files['map_y'])
    rectified.tofile(files['rectified'])
    return {'name': camera['name'], **files}


def main():
    source = open(sys.argv[1]) if len(sys.argv) > 1 else sys.stdin
    request = json.load(source)
    reply = {'opencv': cv2.__version__, 'cameras': [rectify(c) for c in request['cameras']]}
    json.dump(reply, sys.stdout)


if __name__ == '__main__':
    main()
