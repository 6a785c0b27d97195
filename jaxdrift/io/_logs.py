"""Logger files as they are recorded: PX4 ULog (``.ulg``, optional extra ``ulog``: pyulog) and
ROS 1 / ROS 2 bags (``.bag``, a ROS 2 bag folder, ``.db3``, ``.mcap``; optional extra ``ros``:
rosbags). Numpy only besides those; no JAX.

A log holds topics, each written at its own rate with its own timestamps. A channel is named
``TOPIC:INSTANCE.FIELD`` (``sensor_gyro:1.x``; the instance may be left out for 0:
``sensor_combined.gyro_rad[0]``); in a bag ``TOPIC.FIELD`` with the message's field path
(``/imu/data.angular_velocity.x``). :func:`read_log` returns each requested channel on its own
times (seconds); the time-base policy (:mod:`._timebase`) makes the run from them.

Times: ULog uses ``timestamp_sample`` where the topic has it (the time the sensor sampled),
else ``timestamp`` (microseconds); samples with a zero timestamp are dropped. A bag uses the
message's ``header.stamp`` where it is set, else the time the message was recorded.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["LOG_FORMATS", "ULOG_MISSING", "ROS_MISSING", "is_log", "log_format", "parse_channel",
           "read_log", "default_map", "list_topics", "log_info", "ulog_context"]

LOG_FORMATS = ("ulog", "bag")
ULOG_MISSING = ("reading PX4 ULog files (.ulg) needs the optional extra 'ulog': "
                "pip install 'jaxdrift[ulog]' (installs pyulog)")
ROS_MISSING = ("reading ROS bags (.bag, ROS 2 bag folders, .db3, .mcap) needs the optional extra 'ros': "
               "pip install 'jaxdrift[ros]' (installs rosbags)")
#: the contract's attitude columns in a PX4 ULog by default
ULOG_DEFAULTS = {"wx": "sensor_combined:0.gyro_rad[0]", "wy": "sensor_combined:0.gyro_rad[1]",
                 "wz": "sensor_combined:0.gyro_rad[2]", "qw": "vehicle_attitude:0.q[0]",
                 "qx": "vehicle_attitude:0.q[1]", "qy": "vehicle_attitude:0.q[2]", "qz": "vehicle_attitude:0.q[3]"}
#: ULog fields that are means over their own integration window (a delta angle divided by its
#: window, stamped at the window's end), and the field that holds the window [us]
ULOG_WINDOWS = {"gyro_rad": "gyro_integral_dt"}
IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
_IMU_FIELDS = {"wx": "angular_velocity.x", "wy": "angular_velocity.y", "wz": "angular_velocity.z",
               "qw": "orientation.w", "qx": "orientation.x", "qy": "orientation.y", "qz": "orientation.z"}


def log_format(path) -> str | None:
    """``ulog``, ``bag`` or None (not a logger file) from the name (a folder with metadata.yaml is
    a ROS 2 bag)."""
    p = str(path)
    low = p.lower()
    if low.endswith(".ulg"):
        return "ulog"
    if low.endswith((".bag", ".db3", ".mcap")) or (os.path.isdir(p) and os.path.isfile(os.path.join(p, "metadata.yaml"))):
        return "bag"
    return None


def is_log(path) -> bool:
    return log_format(path) is not None


def _label(path) -> str:
    return os.path.basename(str(path).rstrip("/")) or str(path)


def parse_channel(name: str, fmt: str) -> tuple[str, int, str]:
    """``"sensor_gyro:1.x"`` -> ("sensor_gyro", 1, "x"); a bag's ``"/imu.angular_velocity.x"`` ->
    ("/imu", 0, "angular_velocity.x")."""
    topic, dot, field = name.partition(".")
    if not dot or not topic or not field:
        ex = "sensor_gyro:1.x" if fmt == "ulog" else "/imu/data.angular_velocity.x"
        raise InputError(f"--map: {name!r} is not a log channel; write TOPIC{':INSTANCE' if fmt == 'ulog' else ''}"
                         f".FIELD, e.g. {ex}")
    inst = 0
    if fmt == "ulog" and ":" in topic:
        topic, _, i = topic.partition(":")
        if not i.isdigit():
            raise InputError(f"--map: {name!r}: the instance after ':' must be a number (e.g. sensor_gyro:1.x)")
        inst = int(i)
    return topic, inst, field


def canonical(name: str, fmt: str) -> str:
    topic, inst, field = parse_channel(name, fmt)
    return f"{topic}:{inst}.{field}" if fmt == "ulog" else f"{topic}.{field}"


# ----------------------------------------------------------------------------------- ULog

def _pyulog():
    try:
        from pyulog import ULog
    except ImportError:
        raise InputError(ULOG_MISSING) from None
    return ULog


def _open_ulog(path, topics=None):
    ULog = _pyulog()
    try:
        return ULog(str(path), message_name_filter_list=topics)
    except Exception as e:  # noqa: BLE001 - pyulog raises several types for a bad file
        raise InputError(f"{_label(path)}: not a readable ULog file ({e})") from None


def _ulog_times(d) -> np.ndarray:
    """``timestamp_sample`` (when the sensor sampled) where the topic has it and it never goes
    backwards, else ``timestamp`` (when the message was published) [s]."""
    if "timestamp_sample" in d.data:
        ts = np.asarray(d.data["timestamp_sample"], dtype=np.float64) * 1e-6
        live = ts[ts > 0]
        if live.size and np.all(np.diff(live) >= 0):
            return ts
    return np.asarray(d.data["timestamp"], dtype=np.float64) * 1e-6


def _clean_times(fname, name, t, vals):
    """Drop zero stamps and exact repeats; samples out of time order are sorted (all noted)."""
    notes = []
    keep = t > 0
    if not keep.all():
        notes.append(f"{fname}: {name}: {int((~keep).sum())} sample(s) with a zero time stamp dropped")
    t, vals = t[keep], [v[keep] for v in vals]
    d = np.diff(t)
    if np.any(d < 0):
        i = int(np.argmax(d < 0)) + 1
        notes.append(f"{fname}: {name}: {int((d < 0).sum())} sample(s) out of time order (first at sample {i + 1}: "
                     f"{t[i]:.6f} s after {t[i - 1]:.6f} s); sorted by time")
        order = np.argsort(t, kind="stable")
        t, vals = t[order], [v[order] for v in vals]
        d = np.diff(t)
    rep = np.concatenate([[True], d > 0])
    if not rep.all():
        notes.append(f"{fname}: {name}: {int((~rep).sum())} sample(s) repeating the previous time stamp dropped")
        t, vals = t[rep], [v[rep] for v in vals]
    return t, vals, notes


def _window_seconds(d: np.ndarray) -> np.ndarray:
    """A ULog integration window in seconds: PX4 writes it as a float in seconds (v1.8 and before)
    or as whole microseconds (later); no window is shorter than a microsecond or longer than a second."""
    med = float(np.median(d)) if d.size else 0.0
    return d * 1e-6 if med >= 1.0 else d


def _read_ulog(path, want: list[str], optional=()) -> tuple[dict, list[str], dict]:
    fname = _label(path)
    parsed = [parse_channel(w, "ulog") for w in want]
    topics = sorted({p[0] for p in parsed})
    data_list, info, dropouts, formats = _ulog_data(path, topics)
    sets = {(d.name, d.multi_id): d for d in data_list}
    out, notes, windows = {}, [], {}
    for w, (topic, inst, field) in zip(want, parsed):
        d = sets.get((topic, inst))
        if w in optional and (d is None or field not in d.data):
            if not any("no reference" in n for n in notes):
                notes.append(f"{fname}: no {topic}:{inst}.{field} in the log: no reference attitude")
            continue
        if d is None:
            have = sorted(i for n, i in sets if n == topic)
            if have:
                raise InputError(f"{fname}: topic {topic!r} has no instance {inst} (instances: "
                                 f"{', '.join(map(str, have))}; `jaxdrift topics {fname}` lists them)")
            import difflib

            hint = difflib.get_close_matches(topic, list(formats), n=1, cutoff=0.6)
            did = f"; did you mean {hint[0]!r}?" if hint else ""
            raise InputError(f"{fname}: no topic {topic!r} logged{did} (`jaxdrift topics {fname}` lists them)")
        if field not in d.data:
            import difflib

            fields = [f for f in d.data if f != "timestamp"]
            hint = difflib.get_close_matches(field, fields, n=1, cutoff=0.5)
            did = f"; did you mean {hint[0]!r}?" if hint else ""
            raise InputError(f"{fname}: topic {topic}:{inst} has no field {field!r}{did} "
                             f"(fields: {', '.join(fields[:12])}{', ...' if len(fields) > 12 else ''})")
        win = ULOG_WINDOWS.get(field.split("[")[0])
        win = win if win in d.data and "timestamp_sample" not in d.data else None
        cols = [np.asarray(d.data[field], dtype=np.float64)] + \
            ([_window_seconds(np.asarray(d.data[win], dtype=np.float64))] if win else [])
        t, vals, nt = _clean_times(fname, f"{topic}:{inst}", _ulog_times(d), cols)
        notes += [n for n in nt if n not in notes]
        out[w] = (t, vals[0])
        if win and np.all(vals[1] > 0) and np.all(np.isfinite(vals[1])):
            windows[w] = vals[1]
    meta = {k: info.get(k) for k in ("ver_hw", "sys_name", "ver_sw", "ver_sw_release") if k in info}
    if dropouts:
        meta["dropouts"] = len(dropouts)
        meta["dropout_total_s"] = float(sum(dropouts)) * 1e-3
    if windows:
        meta["windows"] = windows  # (taken out by the reader: the time base integrates these)
    return out, notes, meta


def _ulog_data(path, topics):
    """(data sets of ``topics``, info dict, dropout durations [ms], message formats): the fast
    path of :mod:`._ulog_fast` where it reads the log exactly as pyulog would, else pyulog."""
    from ._ulog_fast import read_topics

    ULog = _pyulog()
    try:
        fast = read_topics(path, topics, ULog)
    except Exception as e:  # noqa: BLE001 - pyulog raises several types for a bad file
        raise InputError(f"{_label(path)}: not a readable ULog file ({e})") from None
    if fast is not None:
        return fast
    ulog = _open_ulog(path, topics)
    return ulog.data_list, ulog.msg_info_dict, [d.duration for d in ulog.dropouts], ulog.message_formats


def _ulog_topics(path) -> list[dict]:
    data_list = _ulog_data(path, None)[0]
    rows = []
    for d in sorted(data_list, key=lambda d: (d.name, d.multi_id)):
        t = _ulog_times(d)
        t = t[t > 0]
        dur = float(t[-1] - t[0]) if t.size > 1 else 0.0
        rate = float(1.0 / np.median(np.diff(t))) if t.size > 1 and np.median(np.diff(t)) > 0 else 0.0
        rows.append({"topic": d.name, "instance": int(d.multi_id), "type": d.name,
                     "fields": [f for f in d.data if f not in ("timestamp",)],
                     "samples": int(t.size), "rate_hz": rate, "duration_s": dur})
    return rows


# ----------------------------------------------------------------------------------- ROS bags

def _rosbags():
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(ROS_MISSING) from None
    return AnyReader, get_typestore(Stores.ROS2_HUMBLE)


def _bag_reader(path):
    AnyReader, store = _rosbags()
    p = Path(str(path))
    if p.suffix.lower() in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file():
        p = p.parent
    try:
        r = AnyReader([p], default_typestore=store)
        r.open()
    except Exception as e:  # noqa: BLE001 - rosbags raises several types for a bad bag
        raise InputError(f"{_label(path)}: not a readable ROS bag ({e})") from None
    return r


def _getter(field: str):
    """A fast accessor of a dotted field path (``angular_velocity.x``, ``covariance[0]``)."""
    from operator import attrgetter

    if "[" not in field:
        return attrgetter(field)

    def get(msg):
        v = msg
        for part in field.split("."):
            idx = None
            if part.endswith("]") and "[" in part:
                part, _, i = part[:-1].partition("[")
                idx = int(i)
            v = getattr(v, part)
            if idx is not None:
                v = v[idx]
        return v

    return get


def _stamp(msg, recorded_ns: int) -> float:
    h = getattr(msg, "header", None)
    st = getattr(h, "stamp", None)
    if st is not None:
        s = getattr(st, "sec", 0) + 1e-9 * getattr(st, "nanosec", 0)
        if s > 0:
            return float(s)
    return recorded_ns * 1e-9


def _bag_series(reader, topic, fields, fname):
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        import difflib

        topics = sorted({c.topic for c in reader.connections})
        hint = difflib.get_close_matches(topic, topics, n=1, cutoff=0.5)
        did = f"; did you mean {hint[0]!r}?" if hint else ""
        raise InputError(f"{fname}: no topic {topic!r} in the bag{did} (topics: {', '.join(topics)})")
    from ._bag_fast import imu_series

    fast = imu_series(reader, conns, fields, _stamp, _getter)
    if fast is not None:
        return fast
    getters = [_getter(f) for f in fields]
    t, rows = [], []
    for conn, ts, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        t.append(_stamp(msg, ts))
        try:
            rows.append([g(msg) for g in getters])
        except (AttributeError, IndexError, ValueError, TypeError):
            bad = next(f for f, g in zip(fields, getters) if not _has(g, msg))
            raise InputError(f"{fname}: topic {topic} ({conn.msgtype}) has no field {bad!r}") from None
    try:
        vals = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(fields))
    except (TypeError, ValueError):
        raise InputError(f"{fname}: topic {topic}: the fields {', '.join(fields)} are not all numbers") from None
    return np.asarray(t, dtype=np.float64), [vals[:, j] for j in range(len(fields))]


def _has(getter, msg) -> bool:
    try:
        getter(msg)
    except (AttributeError, IndexError, ValueError, TypeError):
        return False
    return True


def _read_bag(path, want: list[str]) -> tuple[dict, list[str], dict]:
    fname = _label(path)
    by_topic: dict[str, list[tuple[str, str]]] = {}
    for w in want:
        topic, _, field = parse_channel(w, "bag")
        by_topic.setdefault(topic, []).append((w, field))
    out, notes = {}, []
    reader = _bag_reader(path)
    try:
        for topic, items in by_topic.items():
            t, vals = _bag_series(reader, topic, [f for _, f in items], fname)
            t, vals, nt = _clean_times(fname, topic, t, vals)
            notes += nt
            for (w, _), v in zip(items, vals):
                out[w] = (t, v)
    finally:
        reader.close()
    return out, notes, {}


def _bag_fields(msg, prefix="") -> list[str]:
    out = []
    for name in getattr(msg, "__dataclass_fields__", {}):
        v = getattr(msg, name)
        key = f"{prefix}{name}"
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(key)
        elif isinstance(v, np.ndarray) and v.ndim == 1 and v.size <= 16 and v.dtype.kind in "fiu":
            out += [f"{key}[{i}]" for i in range(v.size)]
        elif hasattr(v, "__dataclass_fields__"):
            out += _bag_fields(v, key + ".")
    return out


def _bag_topics(path) -> list[dict]:
    reader = _bag_reader(path)
    rows = []
    try:
        for topic in sorted({c.topic for c in reader.connections}):
            conns = [c for c in reader.connections if c.topic == topic]
            t, first = [], None
            for conn, ts, raw in reader.messages(connections=conns):  # rate from the recording times
                if first is None:
                    first = reader.deserialize(raw, conn.msgtype)
                t.append(ts * 1e-9)
            t = np.sort(np.asarray(t))
            dur = float(t[-1] - t[0]) if t.size > 1 else 0.0
            d = np.diff(t)
            rate = float(1.0 / np.median(d)) if d.size and np.median(d) > 0 else 0.0
            rows.append({"topic": topic, "instance": 0, "type": conns[0].msgtype,
                         "fields": _bag_fields(first) if first is not None else [],
                         "samples": int(t.size), "rate_hz": rate, "duration_s": dur})
    finally:
        reader.close()
    return rows


def _bag_imu_default(path) -> tuple[dict, str, int]:
    """The contract's columns from the bag's Imu topic (the one with most messages); the
    orientation only where it is filled (covariance[0] != -1 and not all zero)."""
    fname = _label(path)
    reader = _bag_reader(path)
    try:
        imus = [c for c in reader.connections if c.msgtype in IMU_TYPES]
        if not imus:
            topics = ", ".join(f"{c.topic} ({c.msgtype})" for c in reader.connections)
            raise InputError(f"{fname}: no sensor_msgs/Imu topic; pick the rates with "
                             f"--map wx=TOPIC.FIELD,... (topics: {topics})")
        counts: dict[str, int] = {}
        for c in imus:
            counts[c.topic] = counts.get(c.topic, 0) + c.msgcount
        topic = max(counts, key=counts.get)
        filled = False
        for conn, _, raw in reader.messages(connections=[c for c in imus if c.topic == topic]):
            m = reader.deserialize(raw, conn.msgtype)
            o = m.orientation
            if m.orientation_covariance[0] != -1 and any((o.w, o.x, o.y, o.z)):
                filled = True
            break
    finally:
        reader.close()
    names = ("wx", "wy", "wz", "qw", "qx", "qy", "qz") if filled else ("wx", "wy", "wz")
    return {c: f"{topic}.{_IMU_FIELDS[c]}" for c in names}, topic, len(counts)


# ----------------------------------------------------------------------------------- entry points

def default_map(path, kind: str = "attitude") -> tuple[dict, list[str]]:
    """The contract's columns in a log when ``--map`` does not say: (map, notes)."""
    fmt = log_format(path)
    if kind != "attitude":
        raise InputError(f"{_label(path)}: a logger file is read as an attitude run (rates wx, wy, wz); "
                         f"a {kind} run needs a table (CSV, Parquet, MF4)")
    if fmt == "ulog":
        return dict(ULOG_DEFAULTS), []
    m, topic, n = _bag_imu_default(path)
    note = [f"{_label(path)}: rates read from the sensor_msgs/Imu topic {topic}"
            + (f" (the one with most messages of {n}; --map picks another)" if n > 1 else "")
            + ("" if "qw" in m else "; its orientation is not filled (no reference)")]
    return m, note


def read_log(path, want: list[str], optional=()) -> tuple[dict, list[str], dict]:
    """Channels ``want`` (``TOPIC:INSTANCE.FIELD`` / ``TOPIC.FIELD``) on their own times:
    ({name: (t [s], values)}, notes, metadata such as the hardware the log names). Channels in
    ``optional`` the log does not have are left out (with a note)."""
    fmt = log_format(path)
    if fmt == "ulog":
        return _read_ulog(path, [canonical(w, fmt) for w in want], {canonical(w, fmt) for w in optional})
    return _read_bag(path, want)


def list_topics(path) -> list[dict]:
    """Every topic (and instance) of a log: topic, instance, type, fields, samples, rate_hz
    (median step), duration_s."""
    if not os.path.exists(str(path)):
        raise InputError(f"{path}: file not found")
    fmt = log_format(path)
    if fmt == "ulog":
        return _ulog_topics(path)
    if fmt == "bag":
        return _bag_topics(path)
    raise InputError(f"{path}: not a logger file (.ulg, .bag, a ROS 2 bag folder, .db3, .mcap)")


def log_info(path) -> dict:
    """What the log says about where it was recorded (ULog: ver_hw, sys_name, ...)."""
    if log_format(path) != "ulog":
        return {}
    ULog = _pyulog()
    try:
        u = ULog(str(path), message_name_filter_list=[], parse_header_only=True)
    except Exception:  # noqa: BLE001
        return {}
    return {k: u.msg_info_dict.get(k) for k in ("ver_hw", "sys_name", "ver_sw") if k in u.msg_info_dict}


# ------------------------------------------------------------------ what a PX4 log says besides

#: the topics :func:`ulog_context` reads (each optional)
_CONTEXT_TOPICS = ["estimator_sensor_bias", "sensor_selection", "estimator_selector_status", "vehicle_attitude",
                   "actuator_armed", "vehicle_status"]


def _step_value(t_ev, v_ev, t):
    """A piecewise-constant signal (value v_ev[i] from t_ev[i] on; the first before it) at ``t``."""
    i = np.clip(np.searchsorted(t_ev, t, side="right") - 1, 0, len(t_ev) - 1)
    return v_ev[i]


def _changes(t, v):
    """(time, before, after) of every change of an integer signal."""
    v = np.asarray(v)
    k = np.nonzero(v[1:] != v[:-1])[0] + 1
    return [(float(t[i]), int(v[i - 1]), int(v[i])) for i in k]


def ulog_context(path, gyro_map: str | None = None) -> dict:
    """What a PX4 log says about its gyro besides the rates, for the attitude diagnosis:

    - ``onboard_bias``: the flight controller's own gyro-bias estimate (``estimator_sensor_bias``),
      ``{"t", "b" (m, 3), "topic", "device_ids"}``: at each time the instance of the primary
      estimator (``estimator_selector_status.primary_instance``, else instance 0), and only its
      samples for the gyro in use (``sensor_selection.gyro_device_id``, which
      ``sensor_combined`` follows); None where the log has none;
    - ``events``: ``[{"t", "kind", "detail"}]`` with ``gyro_switch`` (the primary gyro's device id
      changes), ``estimator_switch`` (the primary estimator instance changes) and
      ``attitude_reset`` (``vehicle_attitude.quat_reset_counter`` steps: a heading or state reset);
    - ``armed``: ``{"t", "armed"}``, whether the motors may run (``actuator_armed.armed``, else
      ``vehicle_status.arming_state`` = 2 in older logs; a step signal from each time on), or
      None: a disarmed vehicle does not shake its gyro.

    ``gyro_map``: the ``wx`` channel read (``TOPIC:INSTANCE.FIELD``): the context applies to
    ``sensor_combined`` only (a mapped ``sensor_gyro`` instance is one sensor: no switch, and the
    estimators' bias is matched by its device id where the log has it). Empty dict for other logs."""
    if log_format(path) != "ulog":
        return {}
    topic = parse_channel(gyro_map, "ulog")[0] if gyro_map else "sensor_combined"
    try:
        data_list = _ulog_data(path, _CONTEXT_TOPICS + (["sensor_gyro"] if topic == "sensor_gyro" else []))[0]
    except InputError:
        return {}
    sets = {}
    for d in data_list:
        sets.setdefault(d.name, {})[d.multi_id] = d

    def tv(d, field):
        t = np.asarray(d.data["timestamp"], np.float64) * 1e-6
        ok = t > 0
        return t[ok], np.asarray(d.data[field])[ok]

    events = []
    sel_t = sel_id = None
    if topic == "sensor_combined" and "sensor_selection" in sets and "gyro_device_id" in sets["sensor_selection"][0].data:
        sel_t, sel_id = tv(sets["sensor_selection"][0], "gyro_device_id")
        live = sel_id != 0
        sel_t, sel_id = sel_t[live], sel_id[live]
        events += [{"t": a, "kind": "gyro_switch", "detail": f"primary gyro device {b} -> {c}"}
                   for a, b, c in _changes(sel_t, sel_id)]
    elif topic == "sensor_gyro" and "sensor_gyro" in sets:
        inst = parse_channel(gyro_map, "ulog")[1]
        d = sets["sensor_gyro"].get(inst)
        if d is not None and "device_id" in d.data:
            sel_t, sel_id = tv(d, "device_id")
            sel_t, sel_id = sel_t[:1], sel_id[:1]
    pri_t = pri = None
    est = sets.get("estimator_selector_status", {}).get(0)
    if est is not None and "primary_instance" in est.data:
        pri_t, pri = tv(est, "primary_instance")
        events += [{"t": a, "kind": "estimator_switch", "detail": f"primary estimator instance {b} -> {c}"}
                   for a, b, c in _changes(pri_t, pri)]
    att = sets.get("vehicle_attitude", {}).get(0)
    if att is not None and "quat_reset_counter" in att.data:
        at, cnt = tv(att, "quat_reset_counter")
        events += [{"t": a, "kind": "attitude_reset", "detail": f"reset counter {b} -> {c}"}
                   for a, b, c in _changes(at, cnt)]
    onboard = None
    esb = sets.get("estimator_sensor_bias", {})
    if esb:
        ts, bs, ids = [], [], set()
        for inst, d in sorted(esb.items()):
            if "gyro_bias[0]" not in d.data:
                continue
            t, _ = tv(d, "gyro_bias[0]")
            b = np.column_stack([tv(d, f"gyro_bias[{i}]")[1] for i in range(3)]).astype(np.float64)
            keep = np.ones(len(t), bool)
            if pri is not None:
                keep &= _step_value(pri_t, pri, t) == inst
            elif len(esb) > 1:
                keep &= inst == min(esb)
            if "gyro_bias_valid" in d.data:
                keep &= tv(d, "gyro_bias_valid")[1].astype(bool)
            if sel_id is not None and "gyro_device_id" in d.data:
                dev = tv(d, "gyro_device_id")[1]
                keep &= dev == _step_value(sel_t, sel_id, t)
                ids |= {int(x) for x in dev[keep]}
            ts.append(t[keep])
            bs.append(b[keep])
        if ts and sum(len(t) for t in ts):
            t = np.concatenate(ts)
            order = np.argsort(t, kind="stable")
            onboard = {"t": t[order], "b": np.concatenate(bs)[order], "topic": "estimator_sensor_bias",
                       "device_ids": sorted(ids)}
    armed = None
    arm = sets.get("actuator_armed", {}).get(0)
    status = sets.get("vehicle_status", {}).get(0)
    if arm is not None and "armed" in arm.data:
        ta, a = tv(arm, "armed")
        a = a.astype(bool)
    elif status is not None and "arming_state" in status.data:  # older logs: 2 is ARMING_STATE_ARMED
        ta, a = tv(status, "arming_state")
        a = a == 2
    else:
        ta = np.zeros(0)
    if len(ta):
        order = np.argsort(ta, kind="stable")
        armed = {"t": ta[order], "armed": np.asarray(a)[order]}
    events.sort(key=lambda e: e["t"])
    return {"onboard_bias": onboard, "events": events, "armed": armed}
