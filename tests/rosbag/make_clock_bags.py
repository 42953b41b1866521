"""Writes bags whose two topics keep different clocks, with an independent writer (the
`rosbags` package), for tests/scans.rs (issue 53):

    python make_clock_bags.py OUT_DIR

A 360-degree scanner nodded by a hobby servo, as in a real RPLIDAR recording: /scan
(sensor_msgs/LaserScan, 0.1 s apart, a beam count that changes from scan to scan between 358
and 362 beams, angle_min -pi, angle_increment 2 pi / n, time_increment scan_time / (n - 1),
scan_time 0.1 s); /lidar_servo_angle (std_msgs/Int32, no header: the servo in whole degrees,
degrees = value - 90), one message 10 ms before each scan, stepping 1 degree per scan in a
+-18 degree nod (stop-and-go); /joint_states (sensor_msgs/JointState, joint `servo`, the same
angle in radians, its header stamped on the scans' clock).

The record times start at 1.7e9 s (1.1e9 s in the first, whose header stamps must fit ROS 2's
int32 seconds). The header stamps are the record times plus an offset:

- clock_ahead_1e9.mcap: + 1e9 s;
- clock_ahead_0.5.mcap: + 0.5 s;
- clock_equal.mcap: + 0 (the recorder's clock);
- clock_boot.db3: the scanner's boot time (the first scan stamped 168 s), as the issue's bag.

OUT_DIR/clocks.json gives per bag the offset and the clock pingcal must choose with each
servo topic, and per scan its record time, beam count, angle_min and angle_increment (the
float32 values, radians) and servo angle (degrees).
"""

import json
import math
import shutil
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

T0_NS = 1_700_000_000 * 1_000_000_000
N_SCANS = 170
PERIOD_NS = 100_000_000
LEAD_NS = 10_000_000


def servo_deg(k):
    """A +-18 degree nod, 1 degree per scan: -18 .. 18 .. -18 ..."""
    p = k % 72
    return -18 + p if p <= 36 else 54 - p


def beams(k):
    return 358 + (k * 7) % 5


def write(path, t0_ns, offset_ns, plugin):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    Time, Header = T['builtin_interfaces/msg/Time'], T['std_msgs/msg/Header']

    def hdr(ns, frame):
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)

    msgs, scans = [], []
    for k in range(N_SCANS):
        rec = t0_ns + k * PERIOD_NS
        deg = servo_deg(k)
        s_rec = rec - LEAD_NS
        msgs.append(('/lidar_servo_angle', s_rec, T['std_msgs/msg/Int32'](data=deg + 90),
                     'std_msgs/msg/Int32'))
        msgs.append(('/joint_states', s_rec,
                     T['sensor_msgs/msg/JointState'](header=hdr(s_rec + offset_ns, ''), name=['servo'],
                                                     position=np.array([math.radians(deg)]),
                                                     velocity=np.zeros(0), effort=np.zeros(0)),
                     'sensor_msgs/msg/JointState'))
        n = beams(k)
        amin = np.float32(-math.pi)
        inc = np.float32(2 * math.pi / n)
        ranges = np.array([2.0 + 0.5 * math.sin(3 * i * 2 * math.pi / n + 0.01 * k) for i in range(n)],
                          dtype=np.float32)
        scan = T['sensor_msgs/msg/LaserScan'](
            header=hdr(rec + offset_ns, 'laser'), angle_min=float(amin),
            angle_max=float(amin + (n - 1) * inc), angle_increment=float(inc),
            time_increment=float(np.float32(0.1 / (n - 1))), scan_time=0.1, range_min=0.15,
            range_max=12.0, ranges=ranges, intensities=np.zeros(0, dtype=np.float32))
        msgs.append(('/scan', rec, scan, 'sensor_msgs/msg/LaserScan'))
        scans.append({'record_ns': rec, 'beams': n, 'angle_min': float(amin),
                      'angle_increment': float(inc), 'servo_deg': deg,
                      'ranges_mm': [float(r) * 1000.0 for r in ranges[:3]]})
    msgs.sort(key=lambda m: m[1])
    tmp = path.with_suffix('.dir')
    shutil.rmtree(tmp, ignore_errors=True)
    w = Writer(tmp, version=9, storage_plugin=plugin)
    w.open()
    conns = {}
    for topic, ns, msg, ty in msgs:
        if topic not in conns:
            conns[topic] = w.add_connection(topic, ty, typestore=ts)
        w.write(conns[topic], ns, ts.serialize_cdr(msg, ty))
    w.close()
    (stored,) = [p for p in tmp.iterdir() if p.suffix in ('.db3', '.mcap')]
    shutil.move(stored, path)
    shutil.rmtree(tmp)
    return scans


def main(out_dir):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cases = {
        # name: (offset of the header clock, ns; the clock pingcal must choose with the
        # Int32 servo (no header), with the JointState servo (stamped on the scans' clock))
        # (ROS 2 stamps are int32 seconds: the record times of this one start at 1.1e9 s)
        'clock_ahead_1e9.mcap': (10**18, 'record', 'header'),
        'clock_ahead_0.5.mcap': (500_000_000, 'record', 'header'),
        'clock_equal.mcap': (0, 'header', 'header'),
        'clock_boot.db3': (168 * 10**9 - T0_NS, 'record', 'header'),
    }
    listing = {}
    for name, (offset, int32, joint) in cases.items():
        plugin = StoragePlugin.SQLITE3 if name.endswith('.db3') else StoragePlugin.MCAP
        t0 = 1_100_000_000 * 10**9 if offset == 10**18 else T0_NS
        scans = write(out / name, t0, offset, plugin)
        listing[name] = {'offset_ns': offset, 'int32': int32, 'joint': joint, 'scans': scans}
    (out / 'clocks.json').write_text(json.dumps(listing) + '\n')


if __name__ == '__main__':
    main(sys.argv[1])
