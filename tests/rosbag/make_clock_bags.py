"""Writes bags whose two topics keep different clocks, with an independent writer (the
`rosbags` package), for tests/scans.rs (issue 53):

    python make_clock_bags.py OUT_DIR
    python make_clock_bags.py --project SIM_DIR
    python make_clock_bags.py --timing OUT_DIR

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

The second form writes every scan of a simulated project (SIM_DIR/scans/S00.csv, v1) as
SIM_DIR/bags/clocks.db3, on two clocks: /scan's header stamps from the scanner's boot (the
first scan at 168 s), its record times from 1.7e9 s; /servo_deg (std_msgs/Float64, no
header: the servo's degrees as the CSV gives them) 10 ms before each scan by the record
clock; and SIM_DIR/project-clocks.toml, which reads them ([lrf.bag] with no `stamps` key:
auto). Calibrated, it must give the CSV's results.

The third form writes OUT_DIR/timing.mcap: a continuous sweep (JointState `servo` at 50 Hz,
30 deg/s from -10 deg, header stamps = record times) and 24 scans 0.1 s apart (20 beams, 1 deg
apart) whose drivers time their beams four ways in turn: time_increment 0.0025 s;
time_increment 0 with scan_time 0.1 s; time_increment -0.0025 s (the last beam first);
time_increment 0.05 s, the whole scan's time.

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


def project(sim_dir):
    sim = Path(sim_dir)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    Time, Header = T['builtin_interfaces/msg/Time'], T['std_msgs/msg/Header']
    header, scans = {}, []
    for line in (sim / 'scans/S00.csv').read_text().splitlines():
        if line.startswith('#'):
            if '=' in line:
                k, v = line[1:].split('=', 1)
                header[k.strip()] = v.strip()
        elif line.strip() and not line.startswith('stamp_s'):
            f = line.split(',')
            scans.append((f[0], f[1], [int(x) for x in f[2:]]))
    amin = math.radians(float(header['angle_min_deg']))
    inc = math.radians(float(header['angle_increment_deg']))
    boot_ns = 168 * 10**9
    msgs = []
    for stamp, servo, ranges in scans:
        sec, _, frac = stamp.partition('.')
        t = int(sec) * 10**9 + int((frac + '000000000')[:9])
        rec = T0_NS + t
        n = len(ranges)
        msgs.append(('/servo_deg', rec - LEAD_NS, T['std_msgs/msg/Float64'](data=float(servo)),
                     'std_msgs/msg/Float64'))
        h = boot_ns + t
        scan = T['sensor_msgs/msg/LaserScan'](
            header=Header(stamp=Time(sec=h // 10**9, nanosec=h % 10**9), frame_id='laser'),
            angle_min=amin, angle_max=amin + (n - 1) * inc, angle_increment=inc,
            time_increment=0.0, scan_time=0.0, range_min=0.02, range_max=30.0,
            ranges=np.array([r / 1000.0 for r in ranges], dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32))
        msgs.append(('/scan', rec, scan, 'sensor_msgs/msg/LaserScan'))
    msgs.sort(key=lambda m: m[1])
    bags = sim / 'bags'
    bags.mkdir(exist_ok=True)
    tmp = bags / 'clocks.dir'
    shutil.rmtree(tmp, ignore_errors=True)
    w = Writer(tmp, version=9, storage_plugin=StoragePlugin.SQLITE3)
    w.open()
    conns = {}
    for topic, ns, msg, ty in msgs:
        if topic not in conns:
            conns[topic] = w.add_connection(topic, ty, typestore=ts)
        w.write(conns[topic], ns, ts.serialize_cdr(msg, ty))
    w.close()
    (stored,) = [p for p in tmp.iterdir() if p.suffix == '.db3']
    shutil.move(stored, bags / 'clocks.db3')
    shutil.rmtree(tmp)
    text = (sim / 'project.toml').read_text()
    lrf = text.replace('scans = ["scans/S00.csv"]\n', '') + (
        '\n[lrf.bag]\nfiles = ["bags/clocks.db3"]\nscan_topic = "/scan"\nservo_topic = "/servo_deg"\n')
    (sim / 'project-clocks.toml').write_text(lrf)


def timing(out_dir):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    Time, Header = T['builtin_interfaces/msg/Time'], T['std_msgs/msg/Header']

    def hdr(ns, frame):
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)

    ramp = lambda ns: -10.0 + 30.0 * (ns - T0_NS) * 1e-9
    msgs = []
    for k in range(130):  # 2.6 s at 50 Hz
        t = T0_NS + k * 20_000_000
        msgs.append(('/joint_states', t,
                     T['sensor_msgs/msg/JointState'](header=hdr(t, ''), name=['servo'],
                                                     position=np.array([math.radians(ramp(t))]),
                                                     velocity=np.zeros(0), effort=np.zeros(0)),
                     'sensor_msgs/msg/JointState'))
    n, inc = 20, math.radians(1.0)
    conventions = [(0.0025, 0.1), (0.0, 0.1), (-0.0025, 0.1), (0.05, 0.1)]
    for k in range(24):
        # reversed beams end at the stamp: stamped later so that all lie within the servo's
        t = T0_NS + 100_000_000 + k * 100_000_000
        ti, st = conventions[k % 4]
        r = np.array([(1500.0 + 5.0 * k + i) / 1000.0 for i in range(n)], dtype=np.float32)
        msgs.append(('/scan', t, T['sensor_msgs/msg/LaserScan'](
            header=hdr(t, 'laser'), angle_min=-math.pi / 4, angle_max=-math.pi / 4 + (n - 1) * inc,
            angle_increment=inc, time_increment=ti, scan_time=st, range_min=0.02, range_max=30.0,
            ranges=r, intensities=np.zeros(0, dtype=np.float32)), 'sensor_msgs/msg/LaserScan'))
    msgs.sort(key=lambda m: m[1])
    tmp = out / 'timing.dir'
    shutil.rmtree(tmp, ignore_errors=True)
    w = Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
    w.open()
    conns = {}
    for topic, ns, msg, ty in msgs:
        if topic not in conns:
            conns[topic] = w.add_connection(topic, ty, typestore=ts)
        w.write(conns[topic], ns, ts.serialize_cdr(msg, ty))
    w.close()
    (stored,) = [p for p in tmp.iterdir() if p.suffix == '.mcap']
    shutil.move(stored, out / 'timing.mcap')
    shutil.rmtree(tmp)


if __name__ == '__main__':
    if sys.argv[1] == '--project':
        project(sys.argv[2])
    elif sys.argv[1] == '--timing':
        timing(sys.argv[2])
    else:
        main(sys.argv[1])
