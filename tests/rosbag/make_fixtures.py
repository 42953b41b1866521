"""Writes the rosbag crate's test bags with an independent writer, the `rosbags` package.

    python make_fixtures.py SCANS.csv OUT_DIR
    python make_fixtures.py --project SIM_DIR

The second form writes every scan of a simulated project (SIM_DIR/scans/S00.csv) as
SIM_DIR/bags/{ros1.bag,ros2.db3,ros2.mcap} and, beside project.toml, project-ros1.toml,
project-db3.toml and project-mcap.toml that read the LRF from those bags ([lrf.bag]).

From a pingcal-scan v1 CSV (a simulated project's scans) it takes 5 scans spread over the
sweep and writes:

- scans.csv: those scans, stamped from T0 = 1.7e9 s (the CSV the bags must decode to);
- ros1.bag, ros1_bz2.bag, ros1_lz4.bag: ROS 1 bags, chunks uncompressed, bz2 and lz4;
- ros2.db3 (sqlite3), ros2.mcap (CDR little endian) and ros2_be.mcap (CDR big endian).

Each has /scan (sensor_msgs/LaserScan, ranges in metres as float32, a no-return as inf,
NaN or 0 in turn), /joint_states (sensor_msgs/JointState, joints `pan` and `servo`, the
servo in radians) and /servo_ticks (std_msgs/Float64, Dynamixel-like ticks: degrees =
ticks * 0.087890625 - 180). The servo stands still during each scan (stop-and-go): two
servo messages per scan, at its first beam and just after its last, and it moves between
scans. /tf (tf2_msgs/TFMessage) turns child frame `servo_link` about y by the servo angle.
/empty (std_msgs/Float64) has no message.

sweep.mcap and sweep.csv: a continuous sweep, the servo turning at 30°/s while it scans,
JointState at 50 Hz; the CSV (v2) gives each scan's servo angle at its first and its last
beam (stamp + 681 * time_increment), from the same ramp.

Issue 37, scans as drivers publish them (`--drivers OUT_DIR`, also part of the default run):

- drivers.bag (ROS 1) and drivers.db3 (ROS 2): 24 scans of 10 to 13 beams (the count
  changes between scans), two of them empty (0 beams, angle_increment inf, as RPLIDAR
  drivers publish), ranges NaN, +inf, -inf, 0, under range_min and over range_max among
  the valid ones, intensities on every scan, one scan repeating the stamp of the one before
  and one stamped before it; the servo stop-and-go, its message 10 ms before each scan, as
  /joint_states (joints `pan`, `tilt`), /servo_int (std_msgs/Int32 ticks: degrees =
  ticks * 0.087890625 - 180) and /tf (`laser_base` -> `servo_link` about y);
  drivers.json: what pingcal must make of them (every scan kept, its servo angle, the
  float32 ranges, the counts).
- dup.db3: 8 scans (drivers' first nine but the empty one) and their servo messages, every
  message stored twice.
- stopgo_10ms.mcap, stopgo_50ms.mcap: a stop-and-go servo stepping 2 encoder ticks per
  scan, one JointState message 10 ms (50 ms) before each scan; stopgo.json: its rest angles.
- sweep_cont.mcap: 24 scans while the servo turns at 30 deg/s from -10 deg, JointState at
  50 Hz (a continuous sweep).
"""

import math
import shutil
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

T0_NS = 1_700_000_000 * 1_000_000_000
SCALE, OFFSET = 0.087890625, -180.0
N_SCANS = 5
TIME_INCREMENT = np.float32(0.1 / 1024)
SERVO_END_S = 0.07  # after the last beam (681 * time_increment = 0.0665 s)


def read_csv(path, subset=True):
    header, scans = {}, []
    for line in Path(path).read_text().splitlines():
        if line.startswith('#'):
            if '=' in line:
                k, v = line[1:].split('=', 1)
                header[k.strip()] = v.strip()
        elif line.startswith('stamp_s'):
            continue
        elif line.strip():
            f = line.split(',')
            scans.append((f[0], f[1], [int(x) for x in f[2:]]))
    if not subset:
        return header, scans
    step = max(1, len(scans) // N_SCANS)
    return header, scans[::step][:N_SCANS]


def stamp_ns(stamp_text):
    sec, _, frac = stamp_text.partition('.')
    return T0_NS + int(sec) * 1_000_000_000 + int((frac + '000000000')[:9])


def write_csv(path, header, scans):
    lines = ['# pingcal-scan v1']
    lines += [f'# {k}={header[k]}' for k in ('angle_min_deg', 'angle_increment_deg', 'range_unit')]
    lines.append('stamp_s,servo_deg,' + ','.join(f'r{i}' for i in range(len(scans[0][2]))))
    for stamp, servo, ranges in scans:
        ns = stamp_ns(stamp) - T0_NS
        lines.append(f'{1_700_000_000 + ns // 1_000_000_000}.{ns % 1_000_000_000 // 1_000_000:03d},{servo},'
                     + ','.join(map(str, ranges)))
    Path(path).write_text('\n'.join(lines) + '\n')


def messages(ts, header, scans, ros1):
    """(topic, time_ns, message) in time order."""
    if 'tf2_msgs/msg/TFMessage' not in ts.types:  # rosbags' Noetic store lacks it
        ts.register(get_types_from_msg('geometry_msgs/TransformStamped[] transforms',
                                       'tf2_msgs/msg/TFMessage'))
    Time = ts.types['builtin_interfaces/msg/Time']
    Header = ts.types['std_msgs/msg/Header']
    LaserScan = ts.types['sensor_msgs/msg/LaserScan']
    JointState = ts.types['sensor_msgs/msg/JointState']
    Float64 = ts.types['std_msgs/msg/Float64']
    TFMessage = ts.types['tf2_msgs/msg/TFMessage']
    TransformStamped = ts.types['geometry_msgs/msg/TransformStamped']
    Transform = ts.types['geometry_msgs/msg/Transform']
    Vector3 = ts.types['geometry_msgs/msg/Vector3']
    Quaternion = ts.types['geometry_msgs/msg/Quaternion']
    amin = math.radians(float(header['angle_min_deg']))
    inc = math.radians(float(header['angle_increment_deg']))
    no_return = [math.inf, math.nan, 0.0]
    out = []
    for k, (stamp, servo, ranges) in enumerate(scans):
        t = stamp_ns(stamp)
        def hdr(ns, frame):
            stamp = Time(sec=ns // 10**9, nanosec=ns % 10**9)
            return Header(seq=k, stamp=stamp, frame_id=frame) if ros1 else Header(stamp=stamp, frame_id=frame)
        r = np.array([r / 1000.0 if r > 0 else no_return[(i + k) % 3] for i, r in enumerate(ranges)],
                     dtype=np.float32)
        n = len(ranges)
        scan = LaserScan(header=hdr(t, 'laser'), angle_min=amin, angle_max=amin + (n - 1) * inc,
                         angle_increment=inc, time_increment=float(TIME_INCREMENT), scan_time=0.1,
                         range_min=0.02, range_max=30.0, ranges=r,
                         intensities=np.zeros(0, dtype=np.float32))
        deg = float(servo)
        for ns in (t, t + int(SERVO_END_S * 1e9)):
            js = JointState(header=hdr(ns, ''), name=['pan', 'servo'],
                            position=np.array([0.25, math.radians(deg)]),
                            velocity=np.zeros(0), effort=np.zeros(0))
            out.append(('/joint_states', ns, js, 'sensor_msgs/msg/JointState'))
            out.append(('/servo_ticks', ns, Float64(data=(deg - OFFSET) / SCALE), 'std_msgs/msg/Float64'))
            h = math.radians(deg) / 2
            tf = TransformStamped(header=hdr(ns, 'laser_base'), child_frame_id='servo_link',
                                  transform=Transform(translation=Vector3(x=0.0, y=0.01, z=0.0),
                                                      rotation=Quaternion(x=0.0, y=math.sin(h), z=0.0, w=math.cos(h))))
            out.append(('/tf', ns, TFMessage(transforms=[tf]), 'tf2_msgs/msg/TFMessage'))
        out.append(('/scan', t, scan, 'sensor_msgs/msg/LaserScan'))
    out.sort(key=lambda m: m[1])
    return out


TYPES = {'/scan': 'sensor_msgs/msg/LaserScan', '/joint_states': 'sensor_msgs/msg/JointState',
         '/servo_ticks': 'std_msgs/msg/Float64', '/tf': 'tf2_msgs/msg/TFMessage',
         '/empty': 'std_msgs/msg/Float64'}
SWEEP_DEG_PER_S = 30.0


def sweep(out, header, scans):
    """sweep.mcap and sweep.csv: the same ranges, taken 0.1 s apart while the servo turns."""
    ts = get_typestore(Stores.ROS2_HUMBLE)
    Time = ts.types['builtin_interfaces/msg/Time']
    Header = ts.types['std_msgs/msg/Header']
    LaserScan = ts.types['sensor_msgs/msg/LaserScan']
    JointState = ts.types['sensor_msgs/msg/JointState']
    hdr = lambda ns: Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id='laser')
    ramp = lambda ns: -10.0 + SWEEP_DEG_PER_S * (ns - T0_NS) * 1e-9
    amin = math.radians(float(header['angle_min_deg']))
    inc = math.radians(float(header['angle_increment_deg']))
    n = len(scans[0][2])
    msgs = []
    for k in range(0, 50):  # 1 s of JointState at 50 Hz
        ns = T0_NS + k * 20_000_000
        msgs.append(('/joint_states', ns, JointState(header=hdr(ns), name=['servo'],
                     position=np.array([math.radians(ramp(ns))]), velocity=np.zeros(0),
                     effort=np.zeros(0)), 'sensor_msgs/msg/JointState'))
    lines = ['# pingcal-scan v2']
    lines += [f'# {k}={header[k]}' for k in ('angle_min_deg', 'angle_increment_deg', 'range_unit')]
    lines.append('stamp_s,servo_deg,servo_end_deg,' + ','.join(f'r{i}' for i in range(n)))
    for k, (_, _, ranges) in enumerate(scans):
        t = T0_NS + 10_000_000 + k * 100_000_000
        r = np.array([x / 1000.0 if x > 0 else math.inf for x in ranges], dtype=np.float32)
        msgs.append(('/scan', t, LaserScan(header=hdr(t), angle_min=amin, angle_max=amin + (n - 1) * inc,
                     angle_increment=inc, time_increment=float(TIME_INCREMENT), scan_time=0.1,
                     range_min=0.02, range_max=30.0, ranges=r, intensities=np.zeros(0, dtype=np.float32)),
                     'sensor_msgs/msg/LaserScan'))
        end = ramp(t) + SWEEP_DEG_PER_S * (n - 1) * float(TIME_INCREMENT)
        lines.append(f'{(t - T0_NS) / 1e9 + 1_700_000_000:.3f},{ramp(t):.12f},{end:.12f},'
                     + ','.join(map(str, ranges)))
    (out / 'sweep.csv').write_text('\n'.join(lines) + '\n')
    msgs.sort(key=lambda m: m[1])
    tmp = out / 'sweep.dir'
    shutil.rmtree(tmp, ignore_errors=True)
    w = Writer2(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
    w.open()
    conns = {t: w.add_connection(t, TYPES[t], typestore=ts) for t in ('/scan', '/joint_states')}
    for topic, ns, msg, ty in msgs:
        w.write(conns[topic], ns, ts.serialize_cdr(msg, ty))
    w.close()
    (stored,) = [p for p in tmp.iterdir() if p.suffix == '.mcap']
    shutil.move(stored, out / 'sweep.mcap')
    shutil.rmtree(tmp)


# geometry.bag: a driver that changes its beam geometry between scans (A A B A C); scan k's
# beam i measures 1000 + 10 k + i mm, the servo stands at 2 k degrees while it scans
GEOMETRIES = {'A': (10, -10.0, 1.0), 'B': (11, -10.0, 1.0), 'C': (10, -5.0, 1.0)}
GEOMETRY_ORDER = 'AABAC'


def geometry(out):
    ts = get_typestore(Stores.ROS1_NOETIC)
    T = ts.types
    hdr = lambda ns, k, frame: T['std_msgs/msg/Header'](
        seq=k, stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)
    path = out / 'geometry.bag'
    path.unlink(missing_ok=True)
    w = Writer1(path)
    w.open()
    cs = w.add_connection('/scan', 'sensor_msgs/msg/LaserScan', typestore=ts)
    cj = w.add_connection('/joint_states', 'sensor_msgs/msg/JointState', typestore=ts)
    for k, g in enumerate(GEOMETRY_ORDER):
        n, a0, step = GEOMETRIES[g]
        t = T0_NS + k * 100_000_000
        for ns in (t, t + int(SERVO_END_S * 1e9)):
            w.write(cj, ns, ts.serialize_ros1(T['sensor_msgs/msg/JointState'](
                header=hdr(ns, k, ''), name=['servo'], position=np.array([math.radians(2.0 * k)]),
                velocity=np.zeros(0), effort=np.zeros(0)), 'sensor_msgs/msg/JointState'))
            if ns == t:
                r = np.array([(1000 + 10 * k + i) / 1000.0 for i in range(n)], dtype=np.float32)
                scan = T['sensor_msgs/msg/LaserScan'](
                    header=hdr(t, k, 'laser'), angle_min=math.radians(a0),
                    angle_max=math.radians(a0 + (n - 1) * step), angle_increment=math.radians(step),
                    time_increment=float(TIME_INCREMENT), scan_time=0.1, range_min=0.02, range_max=30.0,
                    ranges=r, intensities=np.zeros(0, dtype=np.float32))
                w.write(cs, t, ts.serialize_ros1(scan, 'sensor_msgs/msg/LaserScan'))
    w.close()


DRIVER_SCANS = 24
EMPTY = (3, 11)
REPEATED, BACKWARD = 7, 15  # scan 7 has scan 6's stamp; scan 15 is stamped 50 ms before 14
TICK = 0.087890625
RANGE_MIN, RANGE_MAX = 0.15, 12.0


def driver_scans():
    """(stamp_ns, servo message time, servo deg, ticks, n, ranges f32, intensities f32)."""
    out = []
    for k in range(DRIVER_SCANS):
        t = T0_NS + k * 100_000_000
        ticks = 1707 + 3 * k  # -29.970703125 deg and up
        deg = ticks * TICK - 180.0
        stamp = t
        if k == REPEATED:
            stamp = out[-1][0]
        if k == BACKWARD:
            stamp = out[-1][0] - 50_000_000
        n = 0 if k in EMPTY else 10 + k % 4
        r = [(1000.0 + 10.0 * k + 7.3 * i) / 1000.0 for i in range(n)]
        specials = [math.nan, math.inf, -math.inf, 0.0, 0.01, 13.0]
        for j, v in enumerate(specials):
            i = (k + 2 * j) % max(n, 1)
            if n and (k + j) % 3 != 0:
                r[i] = v
        out.append((stamp, t - 10_000_000, deg, ticks, n, np.array(r, dtype=np.float32),
                    np.array([47.0 + i + 0.25 * k for i in range(n)], dtype=np.float32)))
    return out


def masked_reason(v):
    if math.isnan(v):
        return 'nan'
    if math.isinf(v):
        return 'inf'
    if v == 0.0:
        return 'zero'
    if v < np.float32(RANGE_MIN):
        return 'below_min'
    if v > np.float32(RANGE_MAX):
        return 'above_max'
    return None


def driver_messages(ts, ros1, scans):
    T = ts.types
    if 'tf2_msgs/msg/TFMessage' not in T:
        ts.register(get_types_from_msg('geometry_msgs/TransformStamped[] transforms',
                                       'tf2_msgs/msg/TFMessage'))
        T = ts.types
    def hdr(ns, k, frame):
        st = T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9)
        H = T['std_msgs/msg/Header']
        return H(seq=k, stamp=st, frame_id=frame) if ros1 else H(stamp=st, frame_id=frame)
    msgs = []
    for k, (stamp, ts_servo, deg, ticks, n, r, inten) in enumerate(scans):
        a0 = -math.pi / 2
        inc = math.inf if n == 0 else math.radians(1.0)
        scan = T['sensor_msgs/msg/LaserScan'](
            header=hdr(stamp, k, 'laser'), angle_min=0.0 if n == 0 else a0,
            angle_max=0.0 if n == 0 else a0 + (n - 1) * inc, angle_increment=inc,
            time_increment=0.0005, scan_time=0.1, range_min=RANGE_MIN, range_max=RANGE_MAX,
            ranges=r, intensities=inten)
        js = T['sensor_msgs/msg/JointState'](
            header=hdr(ts_servo, k, ''), name=['pan', 'tilt'],
            position=np.array([0.5, math.radians(deg)]), velocity=np.zeros(0), effort=np.zeros(0))
        h = math.radians(deg) / 2
        tf = T['geometry_msgs/msg/TransformStamped'](
            header=hdr(ts_servo, k, 'laser_base'), child_frame_id='servo_link',
            transform=T['geometry_msgs/msg/Transform'](
                translation=T['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.05),
                rotation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=math.sin(h), z=0.0, w=math.cos(h))))
        msgs += [('/joint_states', ts_servo, js, 'sensor_msgs/msg/JointState'),
                 ('/servo_int', ts_servo, T['std_msgs/msg/Int32'](data=ticks), 'std_msgs/msg/Int32'),
                 ('/tf', ts_servo, T['tf2_msgs/msg/TFMessage'](transforms=[tf]), 'tf2_msgs/msg/TFMessage'),
                 # the bag's record time is the arrival: in order even when the stamp is not
                 ('/scan', T0_NS + k * 100_000_000, scan, 'sensor_msgs/msg/LaserScan')]
    msgs.sort(key=lambda m: m[1])
    return msgs


DRIVER_TYPES = {'/scan': 'sensor_msgs/msg/LaserScan', '/joint_states': 'sensor_msgs/msg/JointState',
                '/servo_int': 'std_msgs/msg/Int32', '/tf': 'tf2_msgs/msg/TFMessage'}


def write_bag(path, msgs, ros1, ts, storage=None, twice=False):
    path = Path(path)
    if ros1:
        path.unlink(missing_ok=True)
        w = Writer1(path)
        w.open()
        ser = ts.serialize_ros1
    else:
        tmp = path.with_suffix('.dir')
        shutil.rmtree(tmp, ignore_errors=True)
        w = Writer2(tmp, version=9, storage_plugin=storage)
        w.open()
        ser = ts.serialize_cdr
    topics = sorted({m[0] for m in msgs})
    conns = {t: w.add_connection(t, DRIVER_TYPES.get(t) or TYPES[t], typestore=ts) for t in topics}
    for topic, ns, msg, ty in msgs:
        for _ in range(2 if twice else 1):
            w.write(conns[topic], ns, ser(msg, ty))
    w.close()
    if not ros1:
        (stored,) = [p for p in tmp.iterdir() if p.suffix in ('.db3', '.mcap')]
        shutil.move(stored, path)
        shutil.rmtree(tmp)


def drivers(out):
    import json
    out = Path(out)
    scans = driver_scans()
    ts1 = get_typestore(Stores.ROS1_NOETIC)
    write_bag(out / 'drivers.bag', driver_messages(ts1, True, scans), True, ts1)
    ts2 = get_typestore(Stores.ROS2_HUMBLE)
    write_bag(out / 'drivers.db3', driver_messages(ts2, False, scans), False, ts2, StoragePlugin.SQLITE3)
    write_bag(out / 'dup.db3', driver_messages(ts2, False, [x for k, x in enumerate(scans[:9]) if k not in EMPTY]), False, ts2, StoragePlugin.SQLITE3,
              twice=True)
    # what pingcal must make of drivers.*: the servo's last message at or before each stamp
    servo = sorted((s[1], s[2]) for s in scans)
    want, counts, last = [], {'zero': 0, 'nan': 0, 'inf': 0, 'below_min': 0, 'above_max': 0}, None
    repeated = backward = empty = 0
    for k, (stamp, _, _, _, n, r, inten) in enumerate(scans):
        if n == 0:
            empty += 1
            continue
        if last is not None and stamp < last:
            backward += 1
            continue
        repeated += last == stamp
        last = stamp
        deg = [d for t, d in servo if t <= stamp][-1]
        ranges = []
        for v in r.tolist():
            why = masked_reason(v)
            if why:
                counts[why] += 1
            ranges.append(None if why else v)
        want.append({'message': k, 'stamp_ns': stamp, 'servo_deg': deg, 'ranges_m': ranges,
                     'intensities': inten.tolist()})
    (out / 'drivers.json').write_text(json.dumps(
        {'scans': want, 'empty': empty, 'masked': counts, 'repeated': repeated,
         'backward': backward}, indent=1) + '\n')
    stopgo(out, ts2)


def stopgo(out, ts):
    """stopgo_{10,50}ms.mcap, stopgo.json, sweep_cont.mcap."""
    import json
    T = ts.types
    hdr = lambda ns, f: T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9), frame_id=f)
    n = 20
    inc = math.radians(1.0)
    def scan(t, k):
        r = np.array([(1500.0 + 5.0 * k + i) / 1000.0 for i in range(n)], dtype=np.float32)
        return T['sensor_msgs/msg/LaserScan'](
            header=hdr(t, 'laser'), angle_min=-math.pi / 4, angle_max=-math.pi / 4 + (n - 1) * inc,
            angle_increment=inc, time_increment=0.0025, scan_time=0.1, range_min=0.02, range_max=30.0,
            ranges=r, intensities=np.zeros(0, dtype=np.float32))
    def js(t, deg):
        return T['sensor_msgs/msg/JointState'](header=hdr(t, ''), name=['servo'],
                                               position=np.array([math.radians(deg)]),
                                               velocity=np.zeros(0), effort=np.zeros(0))
    rest = [-20.0 + 2 * TICK * k for k in range(DRIVER_SCANS)]
    for lead_ms in (10, 50):
        msgs = []
        for k in range(DRIVER_SCANS):
            t = T0_NS + k * 100_000_000
            msgs.append(('/joint_states', t - lead_ms * 1_000_000, js(t - lead_ms * 1_000_000, rest[k]),
                         'sensor_msgs/msg/JointState'))
            msgs.append(('/scan', t, scan(t, k), 'sensor_msgs/msg/LaserScan'))
        msgs.sort(key=lambda m: m[1])
        write_bag(out / f'stopgo_{lead_ms}ms.mcap', msgs, False, ts, StoragePlugin.MCAP)
    (out / 'stopgo.json').write_text(json.dumps({'rest_deg': rest, 'period_s': 0.1}) + '\n')
    msgs = []
    ramp = lambda ns: -10.0 + 30.0 * (ns - T0_NS) * 1e-9
    for k in range(0, 130):  # 2.6 s at 50 Hz
        t = T0_NS + k * 20_000_000
        msgs.append(('/joint_states', t, js(t, ramp(t)), 'sensor_msgs/msg/JointState'))
    for k in range(DRIVER_SCANS):
        t = T0_NS + 5_000_000 + k * 100_000_000
        msgs.append(('/scan', t, scan(t, k), 'sensor_msgs/msg/LaserScan'))
    msgs.sort(key=lambda m: m[1])
    write_bag(out / 'sweep_cont.mcap', msgs, False, ts, StoragePlugin.MCAP)


def write_ros1(path, header, scans, compression):
    ts = get_typestore(Stores.ROS1_NOETIC)
    msgs = messages(ts, header, scans, True)
    path.unlink(missing_ok=True)
    w = Writer1(path)
    if compression:
        w.set_compression(compression)
    w.open()
    conns = {t: w.add_connection(t, ty, typestore=ts) for t, ty in TYPES.items()}
    for topic, ns, msg, ty in msgs:
        w.write(conns[topic], ns, ts.serialize_ros1(msg, ty))
    w.close()


def write_ros2(path, header, scans, plugin, little_endian=True):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    msgs = messages(ts, header, scans, False)
    tmp = path.with_suffix('.dir')
    shutil.rmtree(tmp, ignore_errors=True)
    w = Writer2(tmp, version=9, storage_plugin=plugin)
    w.open()
    conns = {t: w.add_connection(t, ty, typestore=ts) for t, ty in TYPES.items()}
    for topic, ns, msg, ty in msgs:
        w.write(conns[topic], ns, ts.serialize_cdr(msg, ty, little_endian=little_endian))
    w.close()
    (stored,) = [p for p in tmp.iterdir() if p.suffix in ('.db3', '.mcap')]
    shutil.move(stored, path)
    shutil.rmtree(tmp)


def write_mcap_compressed(path, header, scans, compression):
    """The messages of ros2.mcap through another independent writer, the `mcap` package's,
    with zstd or lz4 chunks (rosbag2's MCAP writer compresses its chunks with zstd)."""
    from mcap.writer import CompressionType, Writer as McapWriter
    ts = get_typestore(Stores.ROS2_HUMBLE)
    msgs = messages(ts, header, scans, False)
    kind = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4}[compression]
    with open(path, 'wb') as stream:
        w = McapWriter(stream, compression=kind, chunk_size=4096)
        w.start(profile='ros2', library='pingcal fixtures')
        channels = {}
        for topic, ty in TYPES.items():
            text, _ = ts.generate_msgdef(ty, ros_version=2)
            schema = w.register_schema(name=ty, encoding='ros2msg', data=text.encode())
            channels[topic] = w.register_channel(topic=topic, message_encoding='cdr', schema_id=schema)
        for k, (topic, ns, msg, ty) in enumerate(msgs):
            w.add_message(channels[topic], log_time=ns, data=bytes(ts.serialize_cdr(msg, ty)),
                          publish_time=ns, sequence=k)
        w.finish()


def main(src, out_dir):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    header, scans = read_csv(src)
    write_csv(out / 'scans.csv', header, scans)
    write_ros1(out / 'ros1.bag', header, scans, None)
    write_ros1(out / 'ros1_bz2.bag', header, scans, Writer1.CompressionFormat.BZ2)
    write_ros1(out / 'ros1_lz4.bag', header, scans, Writer1.CompressionFormat.LZ4)
    write_ros2(out / 'ros2.db3', header, scans, StoragePlugin.SQLITE3)
    write_ros2(out / 'ros2.mcap', header, scans, StoragePlugin.MCAP)
    write_ros2(out / 'ros2_be.mcap', header, scans, StoragePlugin.MCAP, little_endian=False)
    write_mcap_compressed(out / 'ros2_zstd.mcap', header, scans, 'zstd')
    write_mcap_compressed(out / 'ros2_lz4.mcap', header, scans, 'lz4')
    sweep(out, header, scans[:2])
    geometry(out)
    drivers(out)
    total = 0
    for p in sorted(out.iterdir()):
        total += p.stat().st_size
        print(f'{p.name}: {p.stat().st_size} bytes')
    print(f'total: {total} bytes')


def project(sim_dir):
    sim = Path(sim_dir)
    header, scans = read_csv(sim / 'scans/S00.csv', subset=False)
    bags = sim / 'bags'
    bags.mkdir(exist_ok=True)
    global T0_NS
    T0_NS = 0  # the CSV's own stamps
    write_ros1(bags / 'ros1.bag', header, scans, None)
    write_ros2(bags / 'ros2.db3', header, scans, StoragePlugin.SQLITE3)
    write_ros2(bags / 'ros2.mcap', header, scans, StoragePlugin.MCAP)
    text = (sim / 'project.toml').read_text()
    for name, bag in (('ros1', 'ros1.bag'), ('db3', 'ros2.db3'), ('mcap', 'ros2.mcap')):
        lrf = text.replace('scans = ["scans/S00.csv"]\n', '') + (
            f'\n[lrf.bag]\nfiles = ["bags/{bag}"]\nscan_topic = "/scan"\n'
            'servo_topic = "/joint_states"\nservo_joint = "servo"\n')
        (sim / f'project-{name}.toml').write_text(lrf)
    for p in sorted(bags.iterdir()):
        print(f'{p}: {p.stat().st_size} bytes')


if __name__ == '__main__':
    if sys.argv[1] == '--project':
        project(sys.argv[2])
    elif sys.argv[1] == '--drivers':
        drivers(Path(sys.argv[2]))
    elif sys.argv[1] == '--geometry':
        geometry(Path(sys.argv[2]))
    elif sys.argv[1] == '--compressed':  # SRC OUT_DIR: only the compressed MCAP files
        h, sc = read_csv(sys.argv[2])
        for c in ('zstd', 'lz4'):
            write_mcap_compressed(Path(sys.argv[3]) / f'ros2_{c}.mcap', h, sc, c)
    else:
        main(*sys.argv[1:3])
