"""Writes a bag of a lidar's PointCloud2 and a camera's images with the independent
`rosbags` writer, from a simulated sphere calibration (`pingcal simulate --kind
sphere-calib`), for `pingcal frames` (issue 37).

    python make_frames_bag.py SIM_DIR OUT.mcap raw|compressed

For each frame F01..FNN of SIM_DIR/sphere-calib.toml, in turn: the sphere stands still for
three messages (100 ms apart; the cloud with 3 mm of Gaussian noise on every coordinate,
the raw image with ±1 grey level of noise), then is carried on for two (the cloud shifted
by 0.15 m and 0.30 m, the raw image rolled by 25 and 50 pixels; compressed: the next
frames' PNG files). /points is sensor_msgs/PointCloud2 (x, y, z float32 metres, intensity
float32, ring uint16); /image is sensor_msgs/Image (mono8) or sensor_msgs/CompressedImage
(the frame's PNG file), stamped 5 ms after its cloud. frames.json lists the frames and the
stamps of their still clouds.
"""

import json
import shutil
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

T0_NS = 1_700_000_000 * 1_000_000_000


def read_png_grey8(path):
    """A greyscale PNG as a 2D uint8 array."""
    from PIL import Image
    return np.asarray(Image.open(path).convert('L'))


def frames_of(sim):
    text = (sim / 'sphere-calib.toml').read_text()
    clouds = [l.split('"')[1] for l in text.splitlines() if l.startswith('cloud = ')]
    images = [l.split('"')[1] for l in text.splitlines() if l.startswith('image = ')]
    return list(zip(clouds, images))


def main(sim, out, kind):
    sim, out = Path(sim), Path(out)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    hdr = lambda ns, f: T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9), frame_id=f)
    PF = T['sensor_msgs/msg/PointField']
    fields = [PF(name='x', offset=0, datatype=7, count=1), PF(name='y', offset=4, datatype=7, count=1),
              PF(name='z', offset=8, datatype=7, count=1), PF(name='intensity', offset=12, datatype=7, count=1),
              PF(name='ring', offset=16, datatype=4, count=1)]
    rng = np.random.default_rng(37)
    frames = frames_of(sim)
    clouds = [np.loadtxt(sim / c, comments='#', ndmin=2)[:, :3] for c, _ in frames]
    pngs = [(sim / i).read_bytes() for _, i in frames]
    greys = [read_png_grey8(sim / i) for _, i in frames] if kind == 'raw' else None
    dtype = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('intensity', '<f4'), ('ring', '<u2'),
                      ('pad', '<u2')])

    def cloud_msg(ns, xyz):
        a = np.zeros(len(xyz), dtype=dtype)
        a['x'], a['y'], a['z'] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        a['intensity'] = 100.0
        a['ring'] = np.arange(len(xyz)) % 16
        return T['sensor_msgs/msg/PointCloud2'](
            header=hdr(ns, 'velodyne'), height=1, width=len(xyz), fields=fields, is_bigendian=False,
            point_step=20, row_step=20 * len(xyz), data=np.frombuffer(a.tobytes(), dtype=np.uint8),
            is_dense=True)

    def image_msg(ns, k, still, j):
        if kind == 'raw':
            g = greys[k]
            if still:
                g = np.clip(g.astype(np.int16) + rng.integers(-1, 2, g.shape), 0, 255).astype(np.uint8)
            else:
                g = np.roll(g, 25 * (j + 1), axis=1)
            return T['sensor_msgs/msg/Image'](header=hdr(ns, 'camera'), height=g.shape[0], width=g.shape[1],
                                              encoding='mono8', is_bigendian=0, step=g.shape[1],
                                              data=np.ascontiguousarray(g).reshape(-1)), 'sensor_msgs/msg/Image'
        data = pngs[k] if still else pngs[(k + 1 + j) % len(pngs)]
        return T['sensor_msgs/msg/CompressedImage'](header=hdr(ns, 'camera'), format='png',
                                                    data=np.frombuffer(data, dtype=np.uint8)), \
            'sensor_msgs/msg/CompressedImage'

    tmp = out.with_suffix('.dir')
    shutil.rmtree(tmp, ignore_errors=True)
    w = Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
    w.open()
    image_type = 'sensor_msgs/msg/Image' if kind == 'raw' else 'sensor_msgs/msg/CompressedImage'
    cp = w.add_connection('/points', 'sensor_msgs/msg/PointCloud2', typestore=ts)
    ci = w.add_connection('/image', image_type, typestore=ts)
    listing, t = [], T0_NS
    for k in range(len(frames)):
        still_stamps = []
        for j in range(5):
            still = j < 3
            xyz = clouds[k] + (rng.normal(0.0, 0.003, clouds[k].shape) if still else [0.15 * (j - 2), 0, 0])
            w.write(cp, t, ts.serialize_cdr(cloud_msg(t, xyz), 'sensor_msgs/msg/PointCloud2'))
            msg, ty = image_msg(t + 5_000_000, k, still, j - 3)
            w.write(ci, t + 5_000_000, ts.serialize_cdr(msg, ty))
            if still:
                still_stamps.append(t)
            t += 100_000_000
        listing.append({'frame': frames[k][0], 'points': len(clouds[k]), 'still_ns': still_stamps})
    w.close()
    (stored,) = [p for p in tmp.iterdir() if p.suffix == '.mcap']
    shutil.move(stored, out)
    shutil.rmtree(tmp)
    out.with_suffix('.json').write_text(json.dumps(listing) + '\n')
    print(f'{out}: {len(frames)} frames, {out.stat().st_size} bytes')


if __name__ == '__main__':
    main(*sys.argv[1:4])
