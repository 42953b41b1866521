"""Writes a large bag with the independent `rosbags` writer, for the streaming benchmark:
the simulated project's whole sweep (SIM_DIR/scans/S00.csv) repeated until the bag reaches
SIZE_MB, each repetition 1,000 s after the one before, as /scan (sensor_msgs/LaserScan) and
/joint_states (two messages per scan, the servo standing still while it scans).

    python big_bag.py SIM_DIR OUT.bag|OUT.mcap|OUT.zstd.mcap|OUT.db3 SIZE_MB

OUT.zstd.mcap is written by the `mcap` package's writer with zstd chunks (as rosbag2's MCAP
writer does by default); SIZE_MB then counts the messages' bytes before compression.
"""
import math
import shutil
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import Stores, get_typestore

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "rosbag"))
from make_fixtures import read_csv, stamp_ns, TIME_INCREMENT, SERVO_END_S  # noqa: E402

sim, out, size_mb = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
ros1 = out.suffix == ".bag"
ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
T = ts.types
header, scans = read_csv(sim / "scans" / "S00.csv", subset=False)
amin = math.radians(float(header["angle_min_deg"]))
inc = math.radians(float(header["angle_increment_deg"]))
ser = (lambda m, ty: ts.serialize_ros1(m, ty)) if ros1 else (lambda m, ty: ts.serialize_cdr(m, ty))


def hdr(ns, k, frame):
    stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    H = T["std_msgs/msg/Header"]
    return H(seq=k, stamp=stamp, frame_id=frame) if ros1 else H(stamp=stamp, frame_id=frame)


# one repetition's serialized messages, then the same bytes re-stamped is not possible for
# the header stamps, so each repetition is serialized again (the writer's own cost)
zstd = out.name.endswith(".zstd.mcap")


class ZstdMcap:
    """The rosbags writer's calls used below, on the `mcap` package's zstd writer."""

    def __init__(self, path):
        from mcap.writer import CompressionType, Writer as McapWriter
        self.f = open(path, "wb")
        self.w = McapWriter(self.f, compression=CompressionType.ZSTD)
        self.w.start(profile="ros2", library="pingcal bench")
        self.seq = 0

    def add_connection(self, topic, ty, typestore):
        text, _ = typestore.generate_msgdef(ty, ros_version=2)
        schema = self.w.register_schema(name=ty, encoding="ros2msg", data=text.encode())
        return self.w.register_channel(topic=topic, message_encoding="cdr", schema_id=schema)

    def write(self, conn, ns, data):
        self.w.add_message(conn, log_time=ns, data=bytes(data), publish_time=ns, sequence=self.seq)
        self.seq += 1

    def close(self):
        self.w.finish()
        self.f.close()


if ros1:
    out.unlink(missing_ok=True)
    w = Writer1(out)
    w.open()
elif zstd:
    w = ZstdMcap(out)
else:
    tmp = out.with_suffix(".dir")
    shutil.rmtree(tmp, ignore_errors=True)
    plugin = StoragePlugin.SQLITE3 if out.suffix == ".db3" else StoragePlugin.MCAP
    w = Writer2(tmp, version=9, storage_plugin=plugin)
    w.open()
cs = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=ts)
cj = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
ranges = [np.array([r / 1000.0 if r > 0 else math.inf for r in sc[2]], dtype=np.float32) for sc in scans]
n = len(scans[0][2])
written, rep = 0, 0
while written < size_mb * 1e6:
    for k, (stamp, servo, _) in enumerate(scans):
        t = stamp_ns(stamp) + rep * 1000 * 10**9
        js = [T["sensor_msgs/msg/JointState"](header=hdr(ns, k, ""), name=["servo"],
              position=np.array([math.radians(float(servo))]), velocity=np.zeros(0), effort=np.zeros(0))
              for ns in (t, t + int(SERVO_END_S * 1e9))]
        scan = T["sensor_msgs/msg/LaserScan"](header=hdr(t, k, "laser"), angle_min=amin,
               angle_max=amin + (n - 1) * inc, angle_increment=inc, time_increment=float(TIME_INCREMENT),
               scan_time=0.1, range_min=0.02, range_max=30.0, ranges=ranges[k],
               intensities=np.zeros(0, dtype=np.float32))
        for conn, ns, m, ty in [(cj, t, js[0], "sensor_msgs/msg/JointState"),
                                (cs, t, scan, "sensor_msgs/msg/LaserScan"),
                                (cj, t + int(SERVO_END_S * 1e9), js[1], "sensor_msgs/msg/JointState")]:
            b = ser(m, ty)
            w.write(conn, ns, b)
            written += len(b)
    rep += 1
w.close()
if not ros1 and not zstd:
    (stored,) = [p for p in tmp.iterdir() if p.suffix in (".mcap", ".db3")]
    shutil.move(stored, out)
    shutil.rmtree(tmp)
print(f"{out}: {rep} sweeps, {rep * len(scans)} scans, {out.stat().st_size / 1e6:.0f} MB")
