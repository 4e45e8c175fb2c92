"""ROS 1/2 bags and MCAP files into an mjsysid HDF5 log (`sysid import MODEL BAG --mapping M`).

Reads with the `rosbags` package (ROS 1 .bag, ROS 2 bag folders, .db3 and .mcap files), maps
topics onto the model's actuators, sensors and joints through a small YAML mapping, and writes
the log with mjsysid.write_log (the C++ writer, checked against the model as for CSV import:
sysid/io/log.h). One sequence per bag, named after the file (or folder).

Mapping file (docs/cli.md, "ROS bags and MCAP files"):

    time_base: /joint_states     # the topic whose messages are the samples (default: the first
                                 # topic with sensors or joint states)
    stamp: log                   # every topic's default: log, the time the bag recorded it;
                                 # header, header.stamp (receive time for header-less messages)
    topics:
      /joint_states: {type: JointState}          # by joint name: qpos/qvel, jointpos/jointvel
      /cmd: {field: data, actuators: [a1, a2], stamp: log}   # -> these actuators, in order
      /imu: {field: angular_velocity, sensors: [gyro]}  # -> these sensors (all components)

Samples: one per message of the time base, at its time stamp as recorded (no resampling);
every sensor and joint-state topic gives its latest message at or before that time (zero-order
hold). Commands keep their own times: each message of an actuator topic is a control row at its
own stamp (the log's ctrl_time), held by the fit until the next (a controller that reads the joint
state and then publishes its command has it in force from when it sent it, not from the next
joint state). Samples before every topic has sent a message are dropped. Times are seconds since
the first sample; its absolute stamp (nanoseconds) is the log attribute time_origin_ns.
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys

import mujoco
import numpy as np
import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

import mjsysid

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
# the joints a JointState message describes: one position and one velocity each
_SCALAR_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


# mapping `stamp:` values: the time the bag recorded a message, or its header.stamp
STAMPS = ("log", "header")


class MappingError(ValueError):
    """A mapping that does not fit the model or the bag; the message names file and key."""


def is_bag(path: str) -> bool:
    """A ROS 1 bag, a ROS 2 storage file, an MCAP file, or a ROS 2 bag folder."""
    p = pathlib.Path(path)
    return p.suffix in BAG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").is_file())


def _names(m, obj, count):
    return [mujoco.mj_id2name(m, obj, i) or "" for i in range(count)]


def load_mapping(path: str, m) -> dict:
    """Reads and checks the mapping file against model m. Each topic's entry gets its `stamp`
    (its own, else the top-level one, else log)."""
    try:
        doc = yaml.safe_load(pathlib.Path(path).read_text())
    except (OSError, yaml.YAMLError) as err:
        raise MappingError(f"{path}: cannot read the mapping: {err}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("topics"), dict) or not doc["topics"]:
        raise MappingError(f"{path}: expected a map with `topics:` (topic -> {{type: JointState}}"
                           " or {field: F, actuators: [...], sensors: [...]})")
    unknown = set(doc) - {"topics", "time_base", "stamp"}
    if unknown:
        raise MappingError(f"{path}: unknown key(s) {sorted(unknown)}; valid: topics, time_base,"
                           " stamp")
    default_stamp = doc.get("stamp", "log")
    if default_stamp not in STAMPS:
        raise MappingError(f"{path}: stamp: expected log or header, not {default_stamp!r}")
    actuators = _names(m, mujoco.mjtObj.mjOBJ_ACTUATOR, m.nu)
    sensors = _names(m, mujoco.mjtObj.mjOBJ_SENSOR, m.nsensor)
    topics = {}
    for topic, entry in doc["topics"].items():
        where = f"{path}: topics: {topic}"
        if not isinstance(entry, dict):
            raise MappingError(f"{where}: expected a map")
        stamp = entry.get("stamp", default_stamp)
        if stamp not in STAMPS:
            raise MappingError(f"{where}: stamp: expected log or header, not {stamp!r}")
        topics[topic] = dict(entry, stamp=stamp)
        if entry.get("type") == "JointState":
            if set(entry) - {"type", "stamp"}:
                raise MappingError(f"{where}: a JointState topic takes no other keys than"
                                   " stamp")
            continue
        if "type" in entry:
            raise MappingError(f"{where}: type {entry['type']!r}: the only type is JointState;"
                               " other messages take field:, actuators: and/or sensors:")
        unknown = set(entry) - {"field", "actuators", "sensors", "stamp"}
        if unknown or "field" not in entry:
            raise MappingError(f"{where}: expected field: and actuators: and/or sensors:"
                               f" (and optionally stamp:; unknown: {sorted(unknown)})")
        for key, valid in (("actuators", actuators), ("sensors", sensors)):
            for name in entry.get(key, []):
                if name not in valid:
                    raise MappingError(f"{where}: {key}: '{name}' is not one of the model's"
                                       f" {key}: {', '.join(valid[:20])}")
    # the samples: by default the first topic with sensors or joint states (commands keep their
    # own times), else the first topic
    measuring = [t for t, e in topics.items() if e.get("type") == "JointState" or e.get("sensors")]
    base = doc.get("time_base", (measuring or list(topics))[0])
    if base not in topics:
        raise MappingError(f"{path}: time_base {base!r} is not one of the topics")
    return {"topics": topics, "time_base": base, "stamp": default_stamp}


def _values(msg, field: str, where: str) -> list[float]:
    """The numbers of msg.FIELD (dotted path): a number, an array, or a Vector3/Point
    (x, y, z) or Quaternion (w, x, y, z: MuJoCo's order)."""
    value = msg
    for part in field.split("."):
        if not hasattr(value, part):
            raise MappingError(f"{where}: field {field!r}: the message has no {part!r}")
        value = getattr(value, part)
    if hasattr(value, "w") and hasattr(value, "x"):
        return [value.w, value.x, value.y, value.z]
    if hasattr(value, "x") and hasattr(value, "z"):
        return [value.x, value.y, value.z]
    try:
        return [float(v) for v in np.ravel(np.asarray(value, dtype=float))]
    except (TypeError, ValueError):
        raise MappingError(f"{where}: field {field!r} is not numeric") from None


def _read_topics(bag: str, mapping: dict,
                 warnings: list[str]) -> dict[str, list[tuple[int, object]]]:
    """topic -> [(stamp_ns, message)] in time order, for the mapped topics. Each topic is stamped
    by its mapping's `stamp`; `header` on messages without a header falls back to the time the bag
    recorded them, with a warning appended to warnings (one per topic)."""
    out = {topic: [] for topic in mapping["topics"]}
    headerless = set()
    with AnyReader([pathlib.Path(bag)],
                   default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        present = {c.topic for c in reader.connections}
        missing = [t for t in out if t not in present]
        if missing:
            raise MappingError(f"{bag}: topic(s) {', '.join(missing)} not in the bag; it has: "
                               f"{', '.join(sorted(present))}")
        connections = [c for c in reader.connections if c.topic in out]
        for conn, timestamp, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, conn.msgtype)
            if mapping["topics"][conn.topic]["stamp"] == "header":
                stamp = getattr(getattr(msg, "header", None), "stamp", None)
                if stamp is not None:
                    timestamp = stamp.sec * 1_000_000_000 + stamp.nanosec
                elif conn.topic not in headerless:
                    headerless.add(conn.topic)
                    warnings.append(f"{bag}: {conn.topic}: stamp: header, but its messages "
                                    f"({conn.msgtype}) have no header: stamped with the time the"
                                    " bag recorded them (stamp: log)")
            out[conn.topic].append((timestamp, msg))
    for topic, messages in out.items():
        if not messages:
            raise MappingError(f"{bag}: topic {topic} has no messages")
        messages.sort(key=lambda tm: tm[0])  # stable: equal stamps keep the order received
    return out


def _command_rows(stamps: np.ndarray, first: int, last: int) -> np.ndarray:
    """The messages of a command topic (stamps ascending, ns) the sequence's samples first..last
    (ns) need: from the one in force at the first sample to the first at or after the last; of
    equal stamps the last received (the one in force)."""
    lo = max(int(np.searchsorted(stamps, first, side="right")) - 1, 0)
    hi = min(int(np.searchsorted(stamps, last, side="left")), len(stamps) - 1)
    rows = np.arange(lo, hi + 1)
    return rows[np.append(stamps[rows][1:] != stamps[rows][:-1], True)]


def bag_to_sequence(bag: str, m, mapping: dict, mapping_path: str,
                    warnings: list[str] | None = None):
    """One bag as an mjsysid.Sequence for model m (and its time origin in ns). The warnings of
    reading it (header-less messages stamped `header`) are appended to warnings."""
    topics = _read_topics(bag, mapping, warnings if warnings is not None else [])
    stamps = {topic: np.array([t for t, _ in msgs], dtype=np.int64)
              for topic, msgs in topics.items()}
    base = stamps[mapping["time_base"]]
    # the latest message of each topic at or before each sample; -1 before its first one
    index = {topic: np.searchsorted(times, base, side="right") - 1
             for topic, times in stamps.items()}
    # every sample has every topic's message in force (a command logged before it, too)
    keep = np.all([i >= 0 for i in index.values()], axis=0)
    if not keep.any():
        raise MappingError(f"{bag}: no sample of {mapping['time_base']} comes after a message of"
                           " every mapped topic")
    rows = np.flatnonzero(keep)
    T = len(rows)
    origin = int(base[rows[0]])

    actuators = _names(m, mujoco.mjtObj.mjOBJ_ACTUATOR, m.nu)
    sensors = _names(m, mujoco.mjtObj.mjOBJ_SENSOR, m.nsensor)
    joints = _names(m, mujoco.mjtObj.mjOBJ_JOINT, m.njnt)
    sensor_cols: dict[int, np.ndarray] = {}  # sensor id -> T x dim
    qpos = np.full((T, m.nq), np.nan)
    qvel = np.full((T, m.nv), np.nan)
    # the commands at their own stamps: actuator -> (stamps ns, values)
    commands: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    for topic, entry in mapping["topics"].items():
        where = f"{bag}: {topic}"
        if entry.get("type") == "JointState":
            # by joint name: positions and velocities of hinge and slide joints
            msgs = [topics[topic][i][1] for i in index[topic][rows]]
            for k, msg in enumerate(msgs):
                for j, name in enumerate(msg.name):
                    if name not in joints:
                        continue
                    jid = joints.index(name)
                    if int(m.jnt_type[jid]) not in _SCALAR_JOINTS:
                        continue
                    if len(msg.position) > j:
                        qpos[k, m.jnt_qposadr[jid]] = msg.position[j]
                    if len(msg.velocity) > j:
                        qvel[k, m.jnt_dofadr[jid]] = msg.velocity[j]
            for s in range(m.nsensor):
                jid = m.sensor_objid[s]
                if int(m.sensor_type[s]) == int(mujoco.mjtSensor.mjSENS_JOINTPOS):
                    col = qpos[:, m.jnt_qposadr[jid]]
                elif int(m.sensor_type[s]) == int(mujoco.mjtSensor.mjSENS_JOINTVEL):
                    col = qvel[:, m.jnt_dofadr[jid]]
                else:
                    continue
                if not np.isnan(col).any():
                    sensor_cols[s] = col.reshape(T, 1).copy()
            continue
        names_a = entry.get("actuators", [])
        names_s = entry.get("sensors", [])
        width = len(names_a) + sum(int(m.sensor_dim[sensors.index(n)]) for n in names_s)
        # sensors: the message in force at each sample; commands: their own messages
        picks = {"sensors": index[topic][rows]} if names_s else {}
        if names_a:
            picks["actuators"] = _command_rows(stamps[topic], origin, int(base[rows[-1]]))
        for part, pick in picks.items():
            values = np.array([_values(topics[topic][i][1], entry["field"], where)
                               for i in pick])
            if values.shape[1] != width:
                raise MappingError(f"{where}: field {entry['field']!r} has {values.shape[1]}"
                                   f" numbers; the mapping needs {width} ({len(names_a)}"
                                   f" actuators, sensors {names_s})")
            if part == "actuators":
                for col, name in enumerate(names_a):
                    commands[actuators.index(name)] = (stamps[topic][pick], values[:, col])
                continue
            col = len(names_a)
            for name in names_s:
                s = sensors.index(name)
                dim = int(m.sensor_dim[s])
                sensor_cols[s] = values[:, col:col + dim]
                col += dim

    missing = [actuators[i] for i in range(m.nu) if i not in commands]
    if missing:
        raise MappingError(f"{mapping_path}: actuator(s) {', '.join(missing)} of the model are"
                           " mapped from no topic (every actuator needs its control)")
    # one control row per command stamp of any topic, from the latest of the topics' first
    # commands (at or before the first sample), where every actuator has the command in force; an
    # actuator whose topic sent nothing at a later stamp is NaN there (the log's rule: held from
    # its last command)
    start = max((int(t[0]) for t, _ in commands.values()), default=origin)
    ctrl_stamps = np.unique(np.concatenate([t[t >= start] for t, _ in commands.values()] or
                                           [np.zeros(0, dtype=np.int64)]))
    ctrl = np.full((len(ctrl_stamps), m.nu), np.nan)
    for a, (times, values) in commands.items():
        later = times > start
        ctrl[0, a] = values[int(np.searchsorted(times, start, side="right")) - 1]
        ctrl[np.searchsorted(ctrl_stamps, times[later]), a] = values[later]

    seq = mjsysid.Sequence()
    seq.name = pathlib.Path(bag).stem if not pathlib.Path(bag).is_dir() else \
        pathlib.Path(bag).name
    seq.time = (base[rows] - origin).astype(np.float64) * 1e-9
    if m.nu:
        seq.ctrl_time = (ctrl_stamps - origin).astype(np.float64) * 1e-9
        seq.ctrl = np.ascontiguousarray(ctrl)
    else:  # no actuators: no controls of their own, a T x 0 ctrl
        seq.ctrl = np.zeros((T, 0))
    order = sorted(sensor_cols)
    seq.sensor_names = [sensors[s] for s in order]
    seq.sensor_dims = [int(m.sensor_dim[s]) for s in order]
    seq.sensordata = np.ascontiguousarray(
        np.hstack([sensor_cols[s] for s in order]) if order else np.zeros((T, 0)))
    seq.actuator_names = actuators
    # states only when the joint states cover the whole configuration
    if not np.isnan(qpos).any() and not np.isnan(qvel).any():
        seq.qpos = qpos
        seq.qvel = qvel
    return seq, origin


def import_bags(model: str, bags: list[str], mapping_path: str, out: str,
                sensor_time: str = "pre", time_scale: float = 1.0) -> mjsysid.Log:
    """Imports the bags into the HDF5 log `out` (written atomically, checked against model).

    time_scale multiplies every sample time (`sysid import --time-scale`: stamps that are not
    in nanoseconds, e.g. a simulator clock in other units)."""
    if not (math.isfinite(time_scale) and time_scale > 0):
        raise ValueError(f"--time-scale: expected a finite number > 0, got {time_scale!r}")
    m = mujoco.MjModel.from_xml_path(model)
    mapping = load_mapping(mapping_path, m)
    log = mjsysid.Log()
    log.sensor_time = sensor_time
    sequences = []
    attributes = {"generator": f"mjsysid {mjsysid.__version__} import",
                  "model": str(pathlib.Path(model).resolve()),
                  "mapping": str(pathlib.Path(mapping_path).resolve())}
    for bag in bags:
        warnings: list[str] = []
        try:
            seq, origin = bag_to_sequence(bag, m, mapping, mapping_path, warnings)
        except (MappingError, FileNotFoundError):
            raise
        except Exception as err:  # noqa: BLE001 (rosbags' reader: a corrupt or foreign file)
            raise MappingError(f"{bag}: cannot be read as a ROS 1 bag, ROS 2 bag or MCAP file "
                               f"({type(err).__name__}: {err})") from None
        for w in warnings:
            print(f"sysid import: warning: {w}", file=sys.stderr)
        if time_scale != 1.0:
            seq.time = np.asarray(seq.time) * time_scale
            seq.ctrl_time = np.asarray(seq.ctrl_time) * time_scale
        attributes[f"time_origin_ns.{seq.name}"] = str(origin)
        attributes[f"source.{seq.name}"] = str(pathlib.Path(bag).resolve())
        sequences.append(seq)
    log.sequences = sequences
    log.attributes = attributes
    mjsysid.write_log(out, log, model)
    return log


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="sysid import",
                                     description="ROS bags / MCAP files into an HDF5 log")
    parser.add_argument("model")
    parser.add_argument("bags", nargs="+")
    parser.add_argument("--mapping", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--sensor-time", default="pre", choices=("pre", "post"))
    parser.add_argument("--time-scale", type=float, default=1.0)
    args = parser.parse_args(argv)
    try:
        log = import_bags(args.model, args.bags, args.mapping, args.out, args.sensor_time,
                          args.time_scale)
    except (ValueError, FileNotFoundError) as err:  # MappingError, mjsysid's bad input
        print(f"sysid import: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # noqa: BLE001 (rosbags' reader errors: a corrupt or foreign file)
        print(f"sysid import: {type(err).__name__}: {err}", file=sys.stderr)
        return 2
    print(f"imported {len(log.sequences)} sequence(s) into {args.out}")
    for s in log.sequences:
        print(f"  {s.name:<16} {len(s.time):6d} samples, sensors: {', '.join(s.sensor_names)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
