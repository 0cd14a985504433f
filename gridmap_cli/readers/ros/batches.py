"""Messages decoded in bulk (:mod:`~gridmap_cli.readers.ros.bulk`) into a MessageAccumulator.

Each function does for a whole channel, in log-time order, what the accumulator's per-message
method does message by message, with the same state afterwards: the same frames claimed in the
same order, the same sensor limits (first field of view, largest limits), the same reading keys,
and the same error for the first bad message. Readings are kept as arrays
(:attr:`MessageAccumulator.r_chunks`); poses and transforms go into the same lists.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import MAX_LASER_SAMPLES, too_many_beams
from gridmap_cli.readers.ros.bulk import TF_TYPES, Columns
from gridmap_cli.readers.ros.frames import (
    Transform,
    TransformSeries,
    bad_rotations,
    frame_name,
    rotation_problem,
    yaws_of,
)
from gridmap_cli.readers.ros.messages import MessageAccumulator
from gridmap_cli.readers.ros.messages.fields import _f32, scan_limits_problem
from gridmap_cli.readers.ros.messages.ranges import scan_angles_error
from gridmap_cli.readers.ros.messages.state import _Scan, _Sonar, _Track, scan_angles_disagree

#: Poses whose headings are computed at a time (each atan2 on a Python float).
_YAW_ROWS = 1 << 14


def add_columns(
    acc: MessageAccumulator, source: str, topic: str, type_name: str, cols: Columns
) -> None:
    """Take the decoded messages of one channel (all of them, in log-time order)."""
    acc.message_path = source
    acc.topic_types[topic] = type_name
    if len(cols) == 0:
        return
    plan = acc.plan
    if type_name in TF_TYPES:
        _tf(acc, topic, cols, static=topic in plan.static_topics)
    elif type_name in ("nav_msgs/Odometry", "gridmap.Pose2D"):
        track = {plan.odom_topic: acc.odom, plan.truth_topic: acc.truth}.get(topic)
        if track is None and topic == plan.reference_topic:
            track = acc.reference
        if track is not None:
            _poses(acc, track, topic, cols)
    elif type_name == "gridmap.RangeReading" and topic in acc.range_topics:
        _json_readings(acc, topic, cols)
    elif type_name == "sensor_msgs/Range":
        _ranges(acc, topic, cols)
    elif type_name == "sensor_msgs/LaserScan":
        _scans(acc, topic, cols)


def _stamps(cols: Columns) -> npt.NDArray[np.int64]:
    """Header stamps; a zero stamp falls back to the log time."""
    stamp = cols.arrays["stamp_ns"].astype(np.int64, copy=False)
    if stamp.all():
        return stamp
    return np.where(stamp != 0, stamp, cols.arrays["log_ns"].astype(np.int64, copy=False))


def _frames(cols: Columns, column: str = "frame") -> tuple[npt.NDArray[np.int64], list[str]]:
    """A frame column with names as gridmap compares them (no leading ``/``): indexes into the
    distinct names, in order of first appearance."""
    merged: dict[str, int] = {}
    remap = np.array(
        [merged.setdefault(frame_name(n), len(merged)) for n in cols.names[column]],
        dtype=np.int64,
    )
    index = remap[cols.arrays[column]] if len(remap) else cols.arrays[column].astype(np.int64)
    return index, list(merged)


def _first_rows(index: npt.NDArray[np.int64], n_names: int) -> npt.NDArray[np.int64]:
    """The first row of each name (rows are in order, so names appear in index order)."""
    first = np.full(n_names, len(index), dtype=np.int64)
    np.minimum.at(first, index, np.arange(len(index), dtype=np.int64))
    return first


def _where(acc: MessageAccumulator, topic: str, cols: Columns, row: int) -> str:
    return acc._where(topic, int(cols.arrays["log_ns"][row]))


def _claim_until(
    acc: MessageAccumulator, topic: str, frames: list[str], first: npt.NDArray[np.int64], row: int
) -> None:
    """Claim the frames that appear at or before ``row``, in order of appearance."""
    for i in np.argsort(first, kind="stable").tolist():
        if first[i] <= row:
            acc._claim(frames[i], topic)


def _ranges(acc: MessageAccumulator, topic: str, cols: Columns) -> None:
    a = cols.arrays
    n = len(cols)
    index, frames = _frames(cols)
    first = _first_rows(index, len(frames))
    rmin, rmax = a["min"], a["max"]  # float32: compared and maxed as float64 would be
    with np.errstate(invalid="ignore"):
        bad = ~((rmin >= 0.0) & (rmin < rmax) & np.isfinite(rmax))
    bad_row = int(np.argmax(bad)) if bad.any() else n
    _claim_until(acc, topic, frames, first, bad_row)
    if bad_row < n:
        frame = frames[int(index[bad_row])]
        raise InputFileError(
            acc.message_path,
            f"{_where(acc, topic, cols, bad_row)}: frame '{frame}': need 0 <= min_range < "
            f"max_range, got {_f32(float(rmin[bad_row]))} and {_f32(float(rmax[bad_row]))}",
        )
    most_min = np.full(len(frames), -np.inf, dtype=rmin.dtype)  # (ufunc.at is slow across types)
    most_max = np.full(len(frames), -np.inf, dtype=rmax.dtype)
    np.maximum.at(most_min, index, rmin)
    np.maximum.at(most_max, index, rmax)
    fov = a["fov"]
    keys = np.empty(len(frames), dtype=np.int64)
    for i in np.argsort(first, kind="stable").tolist():
        frame = frames[i]
        sonar = acc.sonars.get(frame)
        if sonar is None:
            row = int(first[i])
            acc.sonars[frame] = _Sonar(float(fov[row]), float(most_min[i]), float(most_max[i]))
        else:
            sonar.min_range = max(sonar.min_range, float(most_min[i]))
            sonar.max_range = max(sonar.max_range, float(most_max[i]))
        keys[i] = acc._key(frame)
    value = a["range"]  # float32 until the log's float64 readings are made
    with np.errstate(invalid="ignore"):
        keep = ~np.isnan(value) & (value >= 0.0)  # NaN: no reading; -inf and below 0: dropped
        value = np.where(value >= rmax, np.float32(np.inf), value)  # at or beyond max: no echo
    acc.r_chunks.append((_stamps(cols)[keep], keys[index[keep]], value[keep], True))


def _scans(acc: MessageAccumulator, topic: str, cols: Columns) -> None:
    a = cols.arrays
    n = len(cols)
    index, frames = _frames(cols)
    first = _first_rows(index, len(frames))
    count = a["count"].astype(np.int64)
    amin, ainc = a["angle_min"].astype(np.float64), a["angle_increment"].astype(np.float64)
    rmin, rmax = a["range_min"].astype(np.float64), a["range_max"].astype(np.float64)
    with np.errstate(invalid="ignore"):
        unusable = ~((rmin >= 0.0) & (rmin < rmax) & np.isfinite(rmax))
    if unusable.any():
        row = int(np.argmax(unusable))
        problem = scan_limits_problem(frames[int(index[row])], float(rmin[row]), float(rmax[row]))
        raise InputFileError(acc.message_path, f"{_where(acc, topic, cols, row)}: {problem}")
    too_many = count > MAX_LASER_SAMPLES
    bad = scan_angles_disagree(amin, a["angle_max"].astype(np.float64), ainc, count) | too_many
    bad_row = int(np.argmax(bad)) if bad.any() else n
    _claim_until(acc, topic, frames, first, bad_row)
    if bad_row < n:
        frame = frames[int(index[bad_row])]
        where = _where(acc, topic, cols, bad_row)
        if too_many[bad_row]:
            raise too_many_beams(
                acc.message_path, int(count[bad_row]), where=f"{where}: laser '{frame}': "
            )
        raise scan_angles_error(
            acc.message_path, where, frame, int(count[bad_row]), float(amin[bad_row]),
            float(a["angle_max"][bad_row]), float(ainc[bad_row]),
        )  # fmt: skip
    known: list[_Scan] = []
    for i, frame in enumerate(frames):
        row = int(first[i])
        scan = acc.scans.get(frame)
        if scan is None:
            scan = _Scan(float(amin[row]), float(ainc[row]), int(count[row]), float(rmin[row]),
                         float(rmax[row]))  # fmt: skip
        known.append(scan)
    for i in np.argsort(first, kind="stable").tolist():  # frames in order of appearance
        acc.scans.setdefault(frames[i], known[i])
    k_min = np.array([k.angle_min for k in known])[index]
    k_inc = np.array([k.angle_increment for k in known])[index]
    k_count = np.array([k.count for k in known], dtype=np.int64)[index]
    changed = (amin != k_min) | (ainc != k_inc) | (count != k_count)
    scan_row, beam, out = scan_beams(cols, count)
    if not changed.any():  # every scan as its frame's first: its beams' keys in order
        base = np.empty(len(frames), dtype=np.int64)
        for i in np.argsort(first, kind="stable").tolist():
            k = known[i]
            keys = acc._beam_keys(frames[i], k, k.book.sensors(k.angle_min, k.angle_increment,
                                                                k.count))  # fmt: skip
            base[i] = keys[0] if len(keys) else 0
            changed |= (index == i) & bool(len(keys) and keys[-1] - keys[0] != len(keys) - 1)
        if not changed.any():
            acc.r_chunks.append((_stamps(cols)[scan_row], base[index][scan_row] + beam, out, True))
            return
    # scans of several geometries: each distinct one's beams looked up once, in log order
    geometry = np.column_stack((index.astype(np.float64), amin, ainc, count.astype(np.float64)))
    _, first_of, which = np.unique(geometry, axis=0, return_index=True, return_inverse=True)
    which = which.reshape(-1)
    tables: list[npt.NDArray[np.int64]] = [np.zeros(0, np.int64)] * len(first_of)
    for g in np.argsort(first_of, kind="stable").tolist():
        row = int(first_of[g])
        k = known[int(index[row])]
        sensors = k.book.sensors(float(amin[row]), float(ainc[row]), int(count[row]))
        tables[g] = acc._beam_keys(frames[int(index[row])], k, sensors)
    offset = np.cumsum([0] + [len(t) for t in tables])[:-1]
    flat = np.concatenate(tables)
    keys = flat[offset[which][scan_row] + beam]
    acc.r_chunks.append((_stamps(cols)[scan_row], keys, out, True))


def scan_beams(
    cols: Columns, count: npt.NDArray[np.int64]
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """The beams of a batch of scans (``count`` beams each) that hold a reading: each one's
    scan (row of ``cols``), its index in the scan, and its range, +inf for no echo (at or
    beyond the scan's ``range_max``). NaN and 0.0 (no reading: no laser measures an echo at
    0 m, and drivers write 0 for a beam that read nothing) and -inf (too close) are left out."""
    assert cols.ranges is not None
    with np.errstate(invalid="ignore"):  # NaN payloads
        ranges = cols.ranges.astype(np.float64)
    row_of = np.repeat(np.arange(len(cols)), count)
    beam = np.arange(len(ranges), dtype=np.int64) - np.repeat(np.cumsum(count) - count, count)
    range_max = cols.arrays["range_max"].astype(np.float64)[row_of]
    with np.errstate(invalid="ignore"):
        valid = ~np.isnan(ranges) & (ranges > 0.0)  # NaN and 0.0: no reading; -inf: too close
        no_echo = valid & (ranges >= range_max)
    return row_of[valid], beam[valid], np.where(no_echo, np.inf, ranges)[valid]


def _json_readings(acc: MessageAccumulator, topic: str, cols: Columns) -> None:
    """gridmap.RangeReading: NaN is no reading; a negative range is an error; the rest (inf
    included) is kept as written, not a float32."""
    a = cols.arrays
    value = a["range"].astype(np.float64)
    keep = ~np.isnan(value)
    bad = keep & (value < 0.0)
    n = int(np.argmax(bad)) if bad.any() else len(value)
    rows = np.flatnonzero(keep[:n])
    # sensor names become keys in order of their first kept reading, as one by one
    sensor = a["sensor"][rows]
    names = cols.names["sensor"]
    first = np.unique(sensor, return_index=True)[1] if len(sensor) else np.zeros(0, np.int64)
    keys = np.zeros(len(names), dtype=np.int64)
    for i in np.sort(first).tolist():
        keys[int(sensor[i])] = acc._key(names[int(sensor[i])])
    if n < len(value):
        raise InputFileError(
            acc.message_path, f"{_where(acc, topic, cols, n)}: negative range {float(value[n])}"
        )
    acc.r_chunks.append((_stamps(cols)[rows], keys[sensor], value[rows], False))


def _poses(acc: MessageAccumulator, track: _Track, topic: str, cols: Columns) -> None:
    a = cols.arrays
    stamps = _stamps(cols)
    xs, ys = a["x"].astype(np.float64), a["y"].astype(np.float64)
    if "theta" in a:  # gridmap.Pose2D
        thetas = a["theta"].astype(np.float64)
    else:
        rotations = np.column_stack([a[k].astype(np.float64) for k in ("qx", "qy", "qz", "qw")])
        bad = bad_rotations(rotations)
        if bad.any():
            row = int(np.argmax(bad))
            qx, qy, qz, qw = rotations[row].tolist()
            problem = rotation_problem((qx, qy, qz, qw))
            raise InputFileError(
                acc.message_path, f"{_where(acc, topic, cols, row)}: orientation {problem}"
            )
        thetas = np.empty(len(stamps))
        for start in range(0, len(stamps), _YAW_ROWS):  # a slice at a time: no 4 whole lists
            part = slice(start, start + _YAW_ROWS)
            thetas[part] = yaws_of(a["qx"][part], a["qy"][part], a["qz"][part], a["qw"][part])
    finite = np.isfinite(a["x"]) & np.isfinite(a["y"]) & np.isfinite(thetas)
    n = len(stamps) if finite.all() else int(np.argmax(~finite))
    if track is acc.odom:
        index, children = _frames(cols, "child")
        counts = np.bincount(index[:n], minlength=len(children))
        for i in np.argsort(_first_rows(index, len(children)), kind="stable").tolist():
            if children[i] and counts[i]:
                acc.odom_children[children[i]] += int(counts[i])
    if n < len(stamps):
        raise InputFileError(
            acc.message_path,
            f"{_where(acc, topic, cols, n)}: pose is not finite ({float(xs[n])}, "
            f"{float(ys[n])}, {float(thetas[n])})",
        )
    track.extend(stamps, np.column_stack((xs, ys, thetas)))


def _tf(acc: MessageAccumulator, topic: str, cols: Columns, static: bool) -> None:
    a = cols.arrays
    parent_index, parents = _frames(cols, "parent")
    child_index, children = _frames(cols, "child")
    names = ("tx", "ty", "tz", "qx", "qy", "qz", "qw")
    values = np.column_stack([a[k].astype(np.float64) for k in names])
    bad = bad_rotations(values[:, 3:]) | ~np.isfinite(values[:, :3]).all(axis=1)
    if bad.any():
        row = int(np.argmax(bad))
        v = values[row].tolist()
        problem = rotation_problem((v[3], v[4], v[5], v[6]))
        if problem is None:
            problem = f"translation {(v[0], v[1], v[2])} is not finite"
        raise InputFileError(
            acc.message_path,
            f"{_where(acc, topic, cols, row)}: transform {parents[int(parent_index[row])]} -> "
            f"{children[int(child_index[row])]}: {problem}",
        )
    if static:
        for p, c, v in zip(
            parent_index.tolist(), child_index.tolist(), values.tolist(), strict=True
        ):
            transform = Transform((v[0], v[1], v[2]), (v[3], v[4], v[5], v[6]))
            acc.tree.add(parents[p], children[c], transform)
        return
    stamps = _stamps(cols)
    pair = parent_index * max(len(children), 1) + child_index
    _, first_row, inverse = np.unique(pair, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    for g in np.argsort(first_row, kind="stable").tolist():
        rows = np.flatnonzero(inverse == g)
        row = int(rows[0])
        key = (parents[int(parent_index[row])], children[int(child_index[row])])
        acc.tf_pairs[key] += len(rows)
        series = acc.tf_series.get(key)
        if series is None:
            series = acc.tf_series[key] = TransformSeries()
        series.stamps.extend(stamps[rows].tolist())
        series.values.extend(map(tuple, values[rows].tolist()))
