"""Conformance goldens: what the four stores of the corridor_loop run in samples/ must give.

samples/ holds one simulated run four times: gridmap CSV, ARIA ``.2d``, MCAP with gridmap's
JSON channels and MCAP with ROS 2 messages. Each must read back to the same canonical record
dump (:func:`canonical_dump`) and build the same map bytes (:func:`map_outputs`).
tests/test_conformance.py checks that against the files in samples/golden/, which only
``make goldens`` (``python -m tests.golden``) writes:

- ``corridor_loop.sha256``: SHA-256 of the canonical dump and of every map output, in
  ``sha256sum`` format;
- ``corridor_loop.dump-head.txt``: the dump's readable head (sensors, sync counts, first records);
- ``corridor_loop.png`` and ``corridor_loop.yaml``: the trinary map itself, as the README's first
  command writes it.
"""

from __future__ import annotations

import hashlib
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.pipeline import BuildOptions, build_map
from gridmap_cli.poses.sync import synchronise
from gridmap_cli.readers import read_log
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RobotDescription, load_robot
from gridmap_cli.writers.map_image import write_map
from gridmap_cli.writers.map_mcap import write_map_mcap

REPO = Path(__file__).resolve().parent.parent
SAMPLES = REPO / "samples"
GOLDEN = SAMPLES / "golden"
RUN = "corridor_loop"
#: The same run in each format gridmap reads and writes.
SAMPLE_LOGS = (
    "corridor_loop.csv",
    "corridor_loop.2d",
    "corridor_loop.mcap",
    "corridor_loop_ros2.mcap",
)
DUMP_NAME = f"{RUN}.dump.txt"
SUMS = GOLDEN / f"{RUN}.sha256"
DUMP_HEAD = GOLDEN / f"{RUN}.dump-head.txt"
#: Lines of the dump kept readable in DUMP_HEAD: header, 16 sensors, sync counts, some records.
HEAD_LINES = 40
#: Map outputs, as ``gridmap build LOG -o NAME [--map-mode MODE]`` writes them (YAML beside).
MAP_OUTPUTS = (
    ("map.pgm", "trinary"),
    ("trinary.png", "trinary"),
    ("scale.png", "scale"),
    ("raw.png", "raw"),
    ("map.mcap", None),
)
REGENERATE = "run `make goldens` and commit samples/golden/ only if the change is intended"


def _decimals(values: npt.NDArray[np.float64]) -> list[str]:
    """Floats rounded to 1e-9, without a sign on zero: a quaternion round trip (ROS 2 stores
    yaw as a quaternion) moves an angle by an ulp or so, far below this."""
    out = [f"{v:.9f}" for v in values.tolist()]
    return ["0.000000000" if s == "-0.000000000" else s for s in out]


def _float32(value: float) -> str:
    """A value that some format holds only as float32, as the shortest decimal of that float32."""
    return np.format_float_positional(np.float32(value), unique=True, trim="-")


def _track_lines(name: str, track: PoseTrack | None) -> Iterable[str]:
    if track is None:
        yield f"{name} none"
        return
    yield f"{name} {len(track)}  # stamp_ns x_m y_m theta_rad"
    columns = (_decimals(track.x_m), _decimals(track.y_m), _decimals(track.theta_rad))
    for stamp, x, y, th in zip(track.stamp_ns.tolist(), *columns, strict=True):
        yield f"{stamp} {x} {y} {th}"


def log_robot(log: RangeLog) -> RobotDescription | None:
    """The robot the log names on its ``robot`` line, as ``gridmap build`` takes it (the samples
    name a preset)."""
    name = log.metadata.get("robot")
    return load_robot(name) if name else None


def canonical_dump(log: RangeLog, robot: RobotDescription | None) -> str:
    """A deterministic text rendering of ``log`` after sync, one record a line.

    Holds the sensors' geometry, the sync counts, the odometry and ground-truth tracks and
    every reading with its sensor's pose (odometry frame). Not the source name nor the log's
    metadata: those are the container's. Floats are rounded to 1e-9, except the beam width,
    which ``sensor_msgs/Range`` carries as float32 (``field_of_view``): it is shown as the
    float32 it rounds to, since the p3at's 25 degrees (0.4363323129985824 rad) come back from
    a ROS 2 log as 0.43633232, 7e-9 away.
    """
    readings, stats = synchronise(log, robot)
    lines = ["gridmap canonical dump 1", f"sensors {len(readings.sensors)}"]
    for s in readings.sensors:
        x, y, yaw, rmin, rmax = _decimals(
            np.array([s.x_m, s.y_m, s.yaw_rad, s.min_range_m, s.max_range_m])
        )
        lines.append(
            f"{s.name} {s.kind} x_m {x} y_m {y} yaw_rad {yaw} "
            f"beam_width_rad {_float32(s.beam_width_rad)} min_range_m {rmin} max_range_m {rmax}"
        )
    lines.append(
        f"sync total {stats.total} used {stats.used} outside_odometry {stats.outside_odometry} "
        f"below_min_range {stats.below_min_range}"
    )
    lines.extend(_track_lines("poses", log.poses))
    lines.extend(_track_lines("truth", log.truth))
    lines.append(f"readings {len(readings)}  # stamp_ns sensor range_m x_m y_m theta_rad")
    names = [s.name for s in readings.sensors]
    columns = (
        _decimals(readings.range_m),
        _decimals(readings.x_m),
        _decimals(readings.y_m),
        _decimals(readings.theta_rad),
    )
    for stamp, k, r, x, y, th in zip(
        readings.stamp_ns.tolist(), readings.sensor.tolist(), *columns, strict=True
    ):
        lines.append(f"{stamp} {names[k]} {r} {x} {y} {th}")
    return "\n".join(lines) + "\n"


def map_outputs(log: RangeLog, robot: RobotDescription | None, folder: Path) -> dict[str, bytes]:
    """Every map output of ``log`` (and each image's YAML), written into ``folder``, by name.

    Does what ``gridmap build LOG -o NAME`` does with its defaults: one map, each image mode,
    and the MCAP map stamped at the last reading.
    """
    result = build_map(log, robot, BuildOptions())
    out: dict[str, bytes] = {}
    for name, mode in MAP_OUTPUTS:
        path = folder / name
        if mode is None:
            stamp = int(log.readings.stamp_ns[-1])
            written = write_map_mcap(path, result.map, stamp_ns=stamp, force=True,
                                     thresholds=(0.65, 0.25))  # fmt: skip
            out[name] = written.read_bytes()
            continue
        image, yaml_path = write_map(path, result.map, mode=mode, force=True)
        out[name] = image.read_bytes()
        out[yaml_path.name] = yaml_path.read_bytes()
    return out


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def read_sums(path: Path = SUMS) -> dict[str, str]:
    """The golden SHA-256 sums, by file name."""
    sums: dict[str, str] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        digest, _, name = line.partition("  ")
        sums[name] = digest
    return sums


def main() -> None:
    """Write samples/golden/ from the CSV sample (the tests check the other formats agree)."""
    log = read_log(SAMPLES / SAMPLE_LOGS[0])
    robot = log_robot(log)
    dump = canonical_dump(log, robot)
    GOLDEN.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        outputs = map_outputs(log, robot, Path(tmp))
        shutil.copyfile(Path(tmp) / "trinary.png", GOLDEN / f"{RUN}.png")
        text = (Path(tmp) / "trinary.yaml").read_text(encoding="utf-8")
        (GOLDEN / f"{RUN}.yaml").write_text(text.replace("trinary.png", f"{RUN}.png"))
    sums = {DUMP_NAME: sha256(dump.encode()), **{n: sha256(b) for n, b in outputs.items()}}
    SUMS.write_text("".join(f"{d}  {n}\n" for n, d in sums.items()), encoding="utf-8")
    head = dump.splitlines(keepends=True)[:HEAD_LINES]
    DUMP_HEAD.write_text("".join(head), encoding="utf-8")
    for path in (SUMS, DUMP_HEAD, GOLDEN / f"{RUN}.png", GOLDEN / f"{RUN}.yaml"):
        print(f"wrote {path.relative_to(REPO)}")


if __name__ == "__main__":
    main()
