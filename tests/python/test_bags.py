"""`sysid import` of ROS 1 bags, ROS 2 bags (sqlite3 and MCAP storage) and plain MCAP files.

Each test writes a small bag with the same libraries a robot would (rosbags; mcap + mcap-ros2-
support) from a simulated pendulum sequence (200 samples, 2 ms apart, absolute ROS stamps from
1.7e9 s): /joint_states (sensor_msgs/JointState: hinge position and velocity) and /cmd
(std_msgs/Float64: the torque). It imports the bag through the real CLI and compares the HDF5
log with what was recorded: controls, sensors (angle, rate: jointpos/jointvel of the hinge) and
the state (qpos, qvel from JointState) bit for bit, times to 1e-12 s.
"""

import subprocess

import numpy as np
import pytest
from mcap_ros2.writer import Writer as McapWriter
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

import mjsysid

T = 200
ORIGIN_NS = 1_700_000_000_123_456_789
STEP_NS = 2_000_000  # the pendulum's timestep, 0.002 s
MAPPING = """\
time_base: /joint_states
topics:
  /joint_states: {type: JointState}
  /cmd: {field: data, actuators: [torque]}
"""
JS = "sensor_msgs/msg/JointState"
F64 = "std_msgs/msg/Float64"


@pytest.fixture
def truth(pendulum):
    seq = mjsysid.simulate(str(pendulum), write=False).sequences[0]
    return {"ctrl": seq.ctrl[:T].copy(), "sensordata": seq.sensordata[:T].copy(),
            "time": seq.time[:T].copy()}


def messages(truth, ts, ros1=False):
    """(topic, msgtype, stamp_ns, message) in time order, rosbags message objects."""
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    out = []
    for k in range(T):
        ns = ORIGIN_NS + k * STEP_NS
        stamp = Time(sec=ns // 10**9, nanosec=ns % 10**9)
        header = Header(seq=k, stamp=stamp, frame_id="") if ros1 else \
            Header(stamp=stamp, frame_id="")
        # the measured joint angle and rate (noisy), as a robot's joint_states carries them
        js = ts.types[JS](header=header, name=["hinge"],
                          position=np.array([truth["sensordata"][k, 0]]),
                          velocity=np.array([truth["sensordata"][k, 1]]),
                          effort=np.array([], dtype=np.float64))
        out.append(("/joint_states", JS, ns, js))
        out.append(("/cmd", F64, ns, ts.types[F64](data=float(truth["ctrl"][k, 0]))))
    return out


def write_ros1(path, truth):
    ts = get_typestore(Stores.ROS1_NOETIC)
    with Writer1(path) as w:
        conns = {t: w.add_connection(t, m, typestore=ts) for t, m in [("/joint_states", JS),
                                                                     ("/cmd", F64)]}
        for topic, msgtype, ns, msg in messages(truth, ts, ros1=True):
            w.write(conns[topic], ns, ts.serialize_ros1(msg, msgtype))


def write_ros2(path, truth, storage):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer2(path, version=9, storage_plugin=storage) as w:
        conns = {t: w.add_connection(t, m, typestore=ts) for t, m in [("/joint_states", JS),
                                                                     ("/cmd", F64)]}
        for topic, msgtype, ns, msg in messages(truth, ts):
            w.write(conns[topic], ns, ts.serialize_cdr(msg, msgtype))


def write_mcap(path, truth):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with open(path, "wb") as f:
        w = McapWriter(f)
        schemas = {m: w.register_msgdef(m, ts.generate_msgdef(m, 2)[0])
                   for m in (JS, F64)}
        for topic, msgtype, ns, msg in messages(truth, ts):
            if msgtype == JS:
                body = {"header": {"stamp": {"sec": msg.header.stamp.sec,
                                             "nanosec": msg.header.stamp.nanosec},
                                   "frame_id": ""},
                        "name": ["hinge"], "position": list(msg.position),
                        "velocity": list(msg.velocity), "effort": []}
            else:
                body = {"data": msg.data}
            w.write_message(topic, schemas[msgtype], body, log_time=ns, publish_time=ns)
        w.finish()


def import_bag(root, sysid, tmp_path, bag, extra=()):
    mapping = tmp_path / "mapping.yaml"
    mapping.write_text(MAPPING)
    out = tmp_path / "imported.h5"
    proc = subprocess.run([sysid, "import", str(root / "models/pendulum.xml"), str(bag),
                           "--mapping", str(mapping), "--out", str(out), *extra],
                          capture_output=True, text=True, timeout=300)
    return proc, out


@pytest.mark.parametrize("kind", ["ros1", "ros2_sqlite3", "ros2_mcap", "mcap"])
def test_import_bag_equals_the_recorded_data(root, sysid, tmp_path, truth, kind):
    bag = {"ros1": tmp_path / "run.bag", "ros2_sqlite3": tmp_path / "run",
           "ros2_mcap": tmp_path / "run", "mcap": tmp_path / "run.mcap"}[kind]
    if kind == "ros1":
        write_ros1(bag, truth)
    elif kind == "mcap":
        write_mcap(bag, truth)
    else:
        write_ros2(bag, truth, StoragePlugin.SQLITE3 if kind == "ros2_sqlite3"
                   else StoragePlugin.MCAP)
    proc, out = import_bag(root, sysid, tmp_path, bag)
    assert proc.returncode == 0, proc.stderr
    log = mjsysid.read_log(str(out))
    (seq,) = log.sequences
    assert seq.name == "run" and log.sensor_time == "pre"
    assert seq.actuator_names == ["torque"] and seq.sensor_names == ["angle", "rate"]
    np.testing.assert_array_equal(seq.ctrl, truth["ctrl"])
    np.testing.assert_array_equal(seq.sensordata, truth["sensordata"])
    # JointState by joint name also gives the state (the hinge is the whole configuration)
    np.testing.assert_array_equal(seq.qpos, truth["sensordata"][:, :1])
    np.testing.assert_array_equal(seq.qvel, truth["sensordata"][:, 1:])
    np.testing.assert_allclose(seq.time, truth["time"], rtol=0, atol=1e-12)
    assert log.attributes["time_origin_ns.run"] == str(ORIGIN_NS)


def test_import_bag_errors_exit_2(root, sysid, tmp_path, truth):
    bag = tmp_path / "run.bag"
    write_ros1(bag, truth)
    mapping = tmp_path / "mapping.yaml"
    # no --mapping
    proc = subprocess.run([sysid, "import", str(root / "models/pendulum.xml"), str(bag),
                           "--out", str(tmp_path / "x.h5")], capture_output=True, text=True)
    assert proc.returncode == 2 and "--mapping" in proc.stderr
    # a topic the bag lacks, an actuator the model lacks
    for text, expected in [(MAPPING.replace("/cmd:", "/command:"), "/command not in the bag"),
                           (MAPPING.replace("[torque]", "[motor]"), "'motor' is not one of")]:
        mapping.write_text(text)
        proc = subprocess.run([sysid, "import", str(root / "models/pendulum.xml"), str(bag),
                               "--mapping", str(mapping), "--out", str(tmp_path / "x.h5")],
                              capture_output=True, text=True)
        assert proc.returncode == 2 and expected in proc.stderr, proc.stderr
        assert proc.stderr.startswith("sysid import: ")
    assert not (tmp_path / "x.h5").exists()
    # a file that is no bag (issue 35: reader errors named no file): exit 2 naming it
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"not a bag at all" * 64)
    mapping.write_text(MAPPING)
    proc = subprocess.run([sysid, "import", str(root / "models/pendulum.xml"), str(junk),
                           "--mapping", str(mapping), "--out", str(tmp_path / "x.h5")],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    assert f"{junk}: cannot be read as a ROS 1 bag" in proc.stderr, proc.stderr
    # stamp: header with a command topic of header-less Float64 (it was a raw AttributeError)
    mapping.write_text("stamp: header\n" + MAPPING)
    proc = subprocess.run([sysid, "import", str(root / "models/pendulum.xml"), str(bag),
                           "--mapping", str(mapping), "--out", str(tmp_path / "x.h5")],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    assert f"{bag}: /cmd: stamp: header, but its messages" in proc.stderr, proc.stderr
    assert "AttributeError" not in proc.stderr
    assert not (tmp_path / "x.h5").exists()
    # no Python with the package
    mapping.write_text(MAPPING)
    proc = subprocess.run([sysid, "import", str(root / "models/pendulum.xml"), str(bag),
                           "--mapping", str(mapping), "--out", str(tmp_path / "x.h5")],
                          capture_output=True, text=True,
                          env={"MJSYSID_PYTHON": str(tmp_path / "no-python")})
    assert proc.returncode == 2 and "no Python at" in proc.stderr, proc.stderr
