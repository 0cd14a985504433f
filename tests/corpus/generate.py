"""Generate gridmap's malformed-input corpus: broken logs of every format gridmap reads, robot
descriptions (YAML and ARIA ``.p``) and world YAML, each with the error it must give.

    python -m tests.corpus.generate OUTDIR     # writes OUTDIR/<case>/... and OUTDIR/cases.json

``tests/corpus/test_corpus.py`` generates the corpus into a temporary folder and runs gridmap on
every case: the exit code, one ``Error:`` line naming the file and the place (``path:line:``,
``path: byte N:``, ``path: message N``) and a fragment of the message, and no output created or
changed. Each case is built from a small valid input by one change, so that what is broken is
exactly what the case's name says.
"""

from __future__ import annotations

import dataclasses
import gzip
import json
import shutil
import struct
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

#: How gridmap is run on a case's input: ``build`` (the input is the log), ``robot`` (build a
#: good CSV log with ``--robot INPUT``), ``world`` (simulate in the world INPUT).
COMMANDS = ("build", "robot", "world")


@dataclass(frozen=True)
class Case:
    """One malformed input and what gridmap must say about it.

    ``input`` is relative to the case's folder; ``place`` is what follows the path in the error
    (``":7: "``, ``": byte "``, ``": message "``); ``fragment`` must appear in the message.
    """

    name: str
    reader: str
    command: str
    input: str
    code: int
    place: str
    fragment: str


Builder = Callable[[Path], None]
_CASES: list[tuple[Case, Builder]] = []


def case(
    name: str, reader: str, input_name: str, place: str, fragment: str,
    command: str = "build", code: int = 1,
) -> Callable[[Builder], Builder]:  # fmt: skip
    """Register a builder writing the case's files into the folder it is given."""

    def register(build: Builder) -> Builder:
        _CASES.append((Case(name, reader, command, input_name, code, place, fragment), build))
        return build

    return register


def text_case(
    name: str, reader: str, input_name: str, text: str | bytes, line: int | None,
    fragment: str, command: str = "build", encoding: str = "utf-8",
) -> None:  # fmt: skip
    """A case whose input is one text file; the error names ``line`` (None: the whole file)."""
    data = text if isinstance(text, bytes) else text.encode(encoding)
    place = f":{line}: " if line is not None else ": "

    def build(folder: Path) -> None:
        (folder / input_name).write_bytes(data)

    case(name, reader, input_name, place, fragment, command)(build)


# ------------------------------------------------------------------------------------------ CSV

CSV_HEAD = "# gridmap-csv: 1\n# robot: p3dx\ntime,x,y,theta,sonar0,sonar1\n"
CSV_ROWS = [f"{k / 10:.1f},{k * 0.05:.2f},0.0,0.0,1.5,2.0\n" for k in range(6)]


def csv_text(replace: dict[int, str] | None = None, head: str = CSV_HEAD) -> str:
    """The good CSV with data row ``i`` (0-based; line ``4 + i``) replaced."""
    rows = [(replace or {}).get(i, row) for i, row in enumerate(CSV_ROWS)]
    return head + "".join(rows)


for _name, _text, _line, _fragment in [
    ("missing-theta", csv_text(head="# robot: p3dx\ntime,x,y,sonar0,sonar1\n"), 2,
     "missing required column 'theta'"),
    ("duplicate-column", csv_text(head="time,x,y,theta,sonar0,sonar0\n"), 1,
     "column 'sonar0' appears twice"),
    ("empty-column-name", csv_text(head="time,x,y,theta,,sonar1\n"), 1, "empty column name"),
    ("partial-truth", csv_text(head="time,x,y,theta,sonar0,true_x\n"), 1,
     "ground truth needs all of"),
    ("too-few-fields", csv_text({2: "0.2,0.1,0.0\n"}), 6, "(truncated file?)"),
    ("too-many-fields", csv_text({3: "0.3,0.15,0.0,0.0,1.5,2.0,9\n"}), 7, "expected 6 fields"),
    ("time-not-a-number", csv_text({1: "zero,0.05,0.0,0.0,1.5,2.0\n"}), 5, "column 'time'"),
    ("time-backwards", csv_text({3: "0.1,0.15,0.0,0.0,1.5,2.0\n"}), 7, "time goes backwards"),
    ("time-repeats", csv_text({3: "0.2,0.15,0.0,0.0,1.5,2.0\n"}), 7, "time repeats"),
    ("time-nan", csv_text({0: "nan,0.0,0.0,0.0,1.5,2.0\n"}), 4, "not a number: 'nan'"),
    ("x-not-a-number", csv_text({4: "0.4,north,0.0,0.0,1.5,2.0\n"}), 8, "column 'x'"),
    ("theta-infinite", csv_text({5: "0.5,0.25,0.0,inf,1.5,2.0\n"}), 9, "pose must be finite"),
    ("negative-range", csv_text({2: "0.2,0.1,0.0,0.0,-1.5,2.0\n"}), 6, "negative range -1.5 m"),
    ("range-not-a-number", csv_text({2: "0.2,0.1,0.0,0.0,1.5,far\n"}), 6, "column 'sonar1'"),
    ("nul-in-field", csv_text({1: "0.1,0.05,0.0,0.0,1\x005,2.0\n"}), 5, "not a number"),
    ("line-too-long", csv_text({2: "0.2" + ",1" * 600_000 + "\n"}), 6, "MAX_LINE_CHARS"),
    ("header-only", CSV_HEAD, 3, "no data rows after the header"),
    # found by the fuzz test: csv's own error for a carriage return inside a row
    ("lone-carriage-return", csv_text({0: "0.\r,0.00,0.0,0.0,1.5,2.0\n"}), 4, "unreadable row"),
]:  # fmt: skip
    text_case(f"csv-{_name}", "csv", "log.csv", _text, _line, _fragment)


# ----------------------------------------------------------------------------------------- ARIA

ARIA_HEAD = (
    "LaserOdometryLog\n#Created by gridmap\n# robot: p3dx\nversion: 4\n"
    "sonarUnit: 0 69 136 90\nsonarUnit: 1 114 119 50\nsonarMaxRange: 5000\n"
)
ARIA_BLOCK = "logTime: {t}\nrobot: {x} 0 0.00\nsonar: 1500 2000\n"


def aria_text(replace: dict[int, str] | None = None, head: str = ARIA_HEAD) -> str:
    """The good ARIA log with whole line ``n`` (1-based) replaced."""
    body = "".join(ARIA_BLOCK.format(t=k / 10, x=k * 50) for k in range(5))
    lines = (head + body).splitlines(keepends=True)
    for number, text in (replace or {}).items():
        lines[number - 1] = text
    return "".join(lines)


for _name, _text, _line, _fragment in [
    ("not-aria", aria_text({1: "LaserLog\n"}), 1, "not an ARIA laser log"),
    ("version-99", aria_text({4: "version: 99\n"}), 4, "version '99'"),
    ("sonar-unit-not-a-number", aria_text({5: "sonarUnit: 0 69 x 90\n"}), 5, "not a number"),
    ("sonar-unit-twice", aria_text({6: "sonarUnit: 0 114 119 50\n"}), 6, "declared twice"),
    ("sonar-unit-short", aria_text({6: "sonarUnit: 1 114\n"}), 6, "expected 4 numbers"),
    ("robot-short", aria_text({12: "robot: 50\n"}), 12, "expected 3 numbers"),
    ("robot-infinite", aria_text({12: "robot: inf 0 0\n"}), 12, "not a finite number"),
    ("logtime-not-a-number", aria_text({11: "logTime: soon\n"}), 11, "not a number"),
    ("sonar-count", aria_text({13: "sonar: 1500 2000 900\n"}), 13, "expected 2 ranges"),
    ("sonar-not-a-number", aria_text({13: "sonar: 1500 near\n"}), 13, "not a number"),
    ("laser-conf-zero", aria_text({7: "sick1conf: -90 90 0\n"}), 7, "samples must be"),
    ("laser-conf-huge", aria_text({7: "sick1conf: -90 90 1e8\n"}), 7, "MAX_LASER_SAMPLES"),
    ("sonar-line-too-long", aria_text({13: "sonar:" + " 0 1500" * 200_000 + "\n"}), 13,
     "MAX_LINE_CHARS"),
]:  # fmt: skip
    text_case(f"aria-{_name}", "aria", "log.2d", _text, _line, _fragment, encoding="latin-1")


# --------------------------------------------------------------------------------------- CARMEN

CARMEN_HEAD = (
    "# CARMEN Logfile\n# message formats defined: PARAM SYNC ODOM FLASER RLASER TRUEPOS\n"
    "PARAM robot_frontlaser_offset 0.0 nohost 0\n"
)


def carmen_lines() -> list[str]:
    out = []
    for k in range(5):
        t = 1.0 + k / 10
        pose = f"{k * 0.05:.9f} 0.000000000 0.000000000"
        out.append(f"ODOM {pose} 0 0 0 {t:.6f} host {t:.6f}\n")
        ranges = "1 2 3 2 1"
        out.append(f"FLASER 5 {ranges} {pose} {pose} {t:.6f} host {t:.6f}\n")
    return out


def carmen_text(replace: dict[int, str] | None = None) -> str:
    """The good CARMEN log with whole line ``n`` (1-based; data from line 4) replaced."""
    lines = (CARMEN_HEAD + "".join(carmen_lines())).splitlines(keepends=True)
    for number, text in (replace or {}).items():
        lines[number - 1] = text
    return "".join(lines)


for _name, _text, _line, _fragment in [
    ("not-a-message", carmen_text({5: "hello world\n"}), 5, "not a CARMEN message line"),
    ("odom-not-a-number", carmen_text({4: "ODOM x 0 0 0 0 0 1.0 host 1.0\n"}), 4, "not a number"),
    ("odom-short", carmen_text({6: "ODOM 0.05 0\n"}), 6, "ODOM"),
    ("flaser-count-not-whole", carmen_text({5: "FLASER 2.5 2 2 0 0 0 0 0 0 1.0 h 1.0\n"}), 5,
     "not a whole number"),
    ("flaser-negative-count", carmen_text({5: "FLASER -3 2 2 0 0 0 0 0 0 1.0 h 1.0\n"}), 5,
     "negative"),
    ("flaser-truncated", carmen_text({7: "FLASER 5 2 2 2\n"}), 7, "FLASER"),
    ("flaser-negative-range", carmen_text({7: "FLASER 5 2 2 -2 2 2 0.05 0 0 0.05 0 0 1.1 h 1.1\n"}),
     7, "negative range"),
    ("flaser-no-count", carmen_text({7: "FLASER\n"}), 7, "num_readings"),
    ("param-no-value", carmen_text({3: "PARAM robot_frontlaser_offset\n"}), 3, "PARAM"),
    ("timestamp-not-a-number", carmen_text({8: "ODOM 0.1 0 0 0 0 0 later host 1.2\n"}), 8,
     "not a number"),
    ("line-too-long", carmen_text({9: "FLASER 181 " + "1.0 " * 300_000 + "\n"}), 9,
     "MAX_LINE_CHARS"),
]:  # fmt: skip
    text_case(f"carmen-{_name}", "carmen", "run.log", _text, _line, _fragment)


def _repeating_odometry(twice: bool) -> str:
    """A corrected log whose ODOM lines only restart at (and repeat) each scan's pose."""
    lines = []
    for k in range(6):
        t, pose = 1.0 + k / 10, f"{k * 0.3:.9f} {k * 0.01:.9f} 0.000000000"
        lines.append(f"FLASER 5 1 2 3 2 1 {pose} {pose} {t:.6f} host {t:.6f}\n")
        lines += [f"ODOM {pose} 0 0 0 {t:.6f} host {t:.6f}\n"] * (2 if twice else 1)
    return CARMEN_HEAD + "".join(lines)


for _name, _data, _line, _fragment in [  # issue 21: gzip bombs fail while decompressing
    ("gzip-nul-bomb", gzip.compress(b"\0" * (16 << 20)), 1, "MAX_LINE_CHARS"),
    ("gzip-endless-line", gzip.compress(CARMEN_HEAD.encode() + b"FLASER 1 " * (2 << 20)), 4,
     "MAX_LINE_CHARS"),
    ("gzip-bomb-second-member", gzip.compress(CARMEN_HEAD.encode()) +
     gzip.compress(b"\r" + b"\0" * (16 << 20)), 4, "MAX_LINE_CHARS"),
]:  # fmt: skip
    text_case(f"carmen-{_name}", "carmen", "run.log.gz", _data, _line, _fragment)

for _name, _twice in [("odometry-only-restarts", False), ("odometry-only-repeats", True)]:
    text_case(f"carmen-{_name}", "carmen", "run.log", _repeating_odometry(_twice), None,
              "--pose odometry: odometry missing")  # fmt: skip


# ----------------------------------------------------------------------------------- robot YAML

ROBOT_HEAD = (
    "gridmap-robot: 1\nname: bot\n"
    "defaults: {kind: sonar, beam_width_deg: 25, min_range_m: 0.1, max_range_m: 5.0}\nsensors:\n"
)
ROBOT_SENSORS = [
    f"  - {{name: sonar{i}, x_m: 0.1, y_m: 0.0, yaw_deg: {i * 20}}}\n" for i in range(16)
]


def robot_text(replace: dict[int, str] | None = None, head: str = ROBOT_HEAD) -> str:
    """The good robot (the p3dx's sensor names) with sensor entry ``i`` (line ``5 + i``)
    replaced."""
    return head + "".join((replace or {}).get(i, s) for i, s in enumerate(ROBOT_SENSORS))


for _name, _text, _line, _fragment in [
    ("yaml-syntax", robot_text({2: "  - {name: sonar2, x_m: 0.1\n"}), 8, "not valid YAML"),
    ("missing-version", robot_text(head="name: bot\nsensors:\n"), None, "gridmap-robot: 1"),
    ("not-a-mapping", "- just\n- a list\n", None, "expected a mapping"),
    ("sensor-no-position", robot_text({1: "  - {name: sonar1, yaw_deg: 20}\n"}), 6,
     "missing keys ['x_m', 'y_m']"),
    ("sensor-twice", robot_text({1: "  - {name: sonar0, x_m: 0.1, y_m: 0, yaw_deg: 20}\n"}), 6,
     "sonar0"),
    ("yaw-not-a-number", robot_text({3: "  - {name: sonar3, x_m: 0.1, y_m: 0, yaw_deg: left}\n"}),
     8, "yaw_deg"),
    ("laser-samples-zero",
     robot_text({0: "  - {name: l, kind: laser, x_m: 0, y_m: 0, yaw_deg: 0, first_deg: -90, "
                    "last_deg: 90, samples: 0}\n"}), 5, "samples must be"),
    ("laser-samples-huge",
     robot_text({0: "  - {name: l, kind: laser, x_m: 0, y_m: 0, yaw_deg: 0, first_deg: -90, "
                    "last_deg: 90, samples: 100000000}\n"}), 5, "MAX_LASER_SAMPLES"),
    ("unknown-kind",
     robot_text({4: "  - {name: sonar4, kind: radar, x_m: 0, y_m: 0, yaw_deg: 0}\n"}), 9,
     "radar"),
]:  # fmt: skip
    text_case(f"robot-{_name}", "robot", "robot.yaml", _text, _line, _fragment, command="robot")


# ----------------------------------------------------------------------------------- ARIA .p

P_RING = "".join(f"SonarUnit {n} {100 + n} {50 - 10 * n} {90 - 20 * n}\n" for n in range(16))
P_HEAD = "ConfigVersion 2.0\nSection General settings\nSubclass bot\nSection Sonar parameters\n"

for _name, _text, _line, _fragment in [
    ("no-sonar-units", P_HEAD + "SonarNum 16\n", 5, "no SonarUnit lines"),
    ("unit-not-a-number", P_HEAD + P_RING.replace("SonarUnit 3 103 20", "SonarUnit 3 103 abc"),
     8, "not a number"),
    ("unit-short", P_HEAD + P_RING + "SonarUnit 16 100 50\n", 21, "at least 4 fields"),
    ("unit-twice", P_HEAD + P_RING + "SonarUnit 1 100 50 90\n", 21, "duplicate SonarUnit 1"),
    ("sonar-num-mismatch", P_HEAD + "SonarNum 8\n" + P_RING, 5, "SonarNum 8"),
    ("max-range-not-a-number", P_HEAD + P_RING + "SonarMaxRange 4.3m\n", 21, "SonarMaxRange"),
    ("laser-autoconnect", P_HEAD + P_RING + "Section Laser parameters\nLaserAutoConnect maybe\n",
     22, "true or false"),
    ("not-a-p-file", "\ngridmap-robot: 1\nname: bot\n", 2, "not an ARIA robot parameter file"),
]:  # fmt: skip
    text_case(f"p-{_name}", "aria-params", "robot.p", _text, _line, _fragment, command="robot")


# ----------------------------------------------------------------------------------- world YAML

WORLD_YAML = (
    "image: world.pgm\nmode: trinary\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
    "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
)


def world_case(name: str, yaml_text: str, line: int | None, fragment: str,
               image: bytes | None = None) -> None:  # fmt: skip
    place = f":{line}: " if line is not None else ": "

    def build(folder: Path) -> None:
        (folder / "world.yaml").write_text(yaml_text)
        # a 40 x 40 room with walls round it, 2 m wide
        rows = [b"\x00" * 40] + [b"\x00" + b"\xfe" * 38 + b"\x00" for _ in range(38)]
        pgm = b"P5\n40 40\n255\n" + b"".join([*rows, b"\x00" * 40])
        (folder / "world.pgm").write_bytes(pgm if image is None else image)

    case(f"world-{name}", "world", "world.yaml", place, fragment, command="world")(build)


for _name, _yaml, _line, _fragment in [
    ("yaml-syntax", WORLD_YAML.replace("origin: [0.0, 0.0, 0.0]", "origin: [0.0, 0.0"), 5,
     "not valid YAML"),
    ("no-image", WORLD_YAML.replace("image: world.pgm\n", ""), None, "missing key 'image'"),
    ("negative-resolution", WORLD_YAML.replace("0.05", "-0.05"), 3, "resolution"),
    ("origin-two-numbers", WORLD_YAML.replace("[0.0, 0.0, 0.0]", "[0.0, 0.0]"), 4, "origin"),
    ("unknown-mode", WORLD_YAML.replace("trinary", "quaternary"), 2, "quaternary"),
    ("thresholds-crossed", WORLD_YAML.replace("0.196", "0.9"), 6, "free_thresh"),
    ("image-missing", WORLD_YAML.replace("world.pgm", "absent.pgm"), 1, "absent.pgm"),
]:  # fmt: skip
    world_case(_name, _yaml, _line, _fragment)
world_case("image-not-an-image", WORLD_YAML, None, "cannot read the image", image=b"P5 garbage")
_CASES[-1] = (dataclasses.replace(_CASES[-1][0], input="world.pgm"), _CASES[-1][1])


# -------------------------------------------------------------------------- ROS recordings


def _ros_bases(folder: Path) -> dict[str, Path]:
    """Good recordings to break, written once per corpus into ``folder``: ROS 2 and ROS 1 MCAP,
    a ROS 1 bag and rosbag2 folders (sqlite3 and MCAP storage)."""
    from tests.readers.bag_helpers import write_bag, write_rosbag2
    from tests.readers.mcap_helpers import Recording, S, drive, one_sonar_log, static_tf

    folder.mkdir(parents=True, exist_ok=True)
    ros2 = one_sonar_log(folder / "ros2.mcap")
    ros1 = folder / "ros1.mcap"
    with Recording(ros1, ros=1) as rec:
        static_tf(rec, rec.transform(0, "base_link", "laser", 0.0, 0.0, 0.0))
        drive(rec)
        scan = {
            "header": rec.header(S, "laser"), "angle_min": -0.1, "angle_max": 0.1,
            "angle_increment": 0.1, "range_min": 0.1, "range_max": 5.0,
            "ranges": [1.0, 1.0, 1.0], "intensities": [],
        }  # fmt: skip
        rec.write("/scan", "sensor_msgs/LaserScan", S, scan)
    from rosbags.rosbag2 import StoragePlugin

    return {
        "ros2": ros2,
        "ros1": ros1,
        "bag": write_bag(ros2, folder / "ros1.bag"),
        "sqlite": write_rosbag2(ros2, folder / "sqlite"),
        "mcap-storage": write_rosbag2(ros2, folder / "mcapbag", storage=StoragePlugin.MCAP),
    }


_BASES: dict[str, Path] = {}


def bases() -> dict[str, Path]:
    if not _BASES:
        import atexit
        import tempfile

        folder = Path(tempfile.mkdtemp(prefix="gridmap-corpus-bases-"))
        atexit.register(shutil.rmtree, folder, True)
        _BASES.update(_ros_bases(folder))
    return _BASES


def _records(data: bytes) -> list[tuple[int, int, int]]:
    out, pos = [], 8
    while pos < len(data) - 8:
        opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        out.append((pos, opcode, length))
        pos += 9 + length
    return out


def _first(data: bytes, opcode: int) -> tuple[int, int]:
    return next((pos, n) for pos, op, n in _records(data) if op == opcode)


def mcap_case(name: str, base: str, place: str, fragment: str,
              change: Callable[[bytearray], None]) -> None:  # fmt: skip
    def build(folder: Path) -> None:
        data = bytearray(bases()[base].read_bytes())
        change(data)
        (folder / "log.mcap").write_bytes(bytes(data))

    case(f"mcap-{name}", "mcap", "log.mcap", place, fragment)(build)


def _flip(offset_of: Callable[[bytearray], int], mask: int = 0xFF) -> Callable[[bytearray], None]:
    def change(data: bytearray) -> None:
        data[offset_of(data)] ^= mask

    return change


def _pack(
    offset_of: Callable[[bytearray], int], fmt: str, value: int
) -> Callable[[bytearray], None]:
    def change(data: bytearray) -> None:
        struct.pack_into(fmt, data, offset_of(data), value)

    return change


CHUNK, MESSAGE_INDEX, CHUNK_INDEX, DATA_END = 0x06, 0x07, 0x08, 0x0F
mcap_case("bad-magic", "ros2", ": byte 0: ", "not an MCAP file", _flip(lambda d: 1))
mcap_case("truncated", "ros2", ": byte ", "no valid footer",
          lambda d: d.__delitem__(slice(len(d) // 2, None)))  # fmt: skip
mcap_case("zstd-chunk-flipped", "ros2", ": byte ", "chunk",
          _flip(lambda d: _first(d, CHUNK)[0] + 80))  # fmt: skip
mcap_case("chunk-crc-field", "ros2", ": byte ", "chunk CRC mismatch",
          _flip(lambda d: _first(d, CHUNK)[0] + 9 + 24, 0x01))  # fmt: skip
mcap_case("summary-flipped", "ros2", ": byte ", "summary CRC mismatch",
          _flip(lambda d: len(d) - 8 - 29 - 30, 0x01))  # fmt: skip
mcap_case("record-length-lie", "ros2", ": byte ", "claims",
          _pack(lambda d: _first(d, MESSAGE_INDEX)[0] + 1, "<Q", 1 << 40))  # fmt: skip
mcap_case("chunk-records-length-lie", "ros2", ": byte ", "bytes of records",
          _pack(lambda d: _first(d, CHUNK)[0] + 9 + 36 + 4, "<Q", 7))  # fmt: skip
mcap_case("chunk-size-beyond-limit", "ros2", ": byte ", "MAX_CHUNK_BYTES",
          _pack(lambda d: _first(d, CHUNK)[0] + 9 + 16, "<Q", 1 << 50))  # fmt: skip
mcap_case("chunk-index-lie", "ros2", ": byte ", "chunk index points at",
          _pack(lambda d: _first(d, CHUNK_INDEX)[0] + 9 + 16, "<Q", 3))  # fmt: skip
mcap_case("footer-moved", "ros2", ": byte ", "footer",
          lambda d: d.__setitem__(slice(len(d) - 8, len(d) - 8), b"\x00"))  # fmt: skip


def edited_mcap_case(name: str, base: str, place: str, fragment: str,
                     message: Callable[[str, bytes], bytes] | None = None,
                     schema: Callable[[str, bytes], bytes] | None = None) -> None:  # fmt: skip
    """A recording whose messages or schemas are changed and CRCs recomputed: damage only
    the decoders can catch."""
    from tests.corpus.mcap_edit import edit_mcap

    def build(folder: Path) -> None:
        edit_mcap(bases()[base], folder / "log.mcap",
                  message or (lambda t, d: d), schema or (lambda n, d: d))  # fmt: skip

    case(f"mcap-{name}", "mcap", "log.mcap", place, fragment)(build)


def _scan_claims(topic: str, data: bytes) -> bytes:
    if topic != "/scan":
        return data
    at = 16 + struct.unpack_from("<I", data, 12)[0] + 28
    return data[:at] + struct.pack("<I", 0x7FFFFFFF) + data[at + 4 :]


edited_mcap_case("ros1-array-claims-gigabytes", "ros1", ": message 1 of /scan ", "does not decode",
                 message=_scan_claims)  # fmt: skip
edited_mcap_case(
    "ros1-schema-does-not-parse",
    "ros1",
    ": /scan: ",
    "does not parse",
    schema=lambda n, d: b"float32[ ranges" if n.endswith("LaserScan") else d,
)
edited_mcap_case(
    "ros2-schema-does-not-parse",
    "ros2",
    ": /sonar: ",
    "does not parse",
    schema=lambda n, d: b"float32[ range\n(((" if n.endswith("Range") else d,
)
edited_mcap_case("ros2-message-truncated", "ros2", ": message ", "does not decode",
                 message=lambda t, d: d[:10] if t == "/sonar" else d)  # fmt: skip
edited_mcap_case("ros2-odometry-emptied", "ros2", ": message ", "does not decode",
                 message=lambda t, d: b"" if t == "/odom" else d)  # fmt: skip
edited_mcap_case(
    "ros2-cdr-string-length-lie",
    "ros2",
    ": message ",
    "does not decode",
    message=lambda t, d: d[:12] + b"\xff\xff\xff\x7f" + d[16:] if t == "/sonar" else d,
)


# issue 21: a schema that does not match its messages' type (fields missing, renamed, retyped):
# the decoder gives a message without the type's fields; one line naming topic and message

HEADER_DEFS = (
    "=" * 80 + "\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
    + "=" * 80 + "\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
)  # fmt: skip


def _schema_of(type_end: str, text: str) -> Callable[[str, bytes], bytes]:
    return lambda n, d: text.encode() if n.endswith(type_end) else d


for _name, _base, _topic, _type, _schema, _fragment in [
    ("range-schema-lacks-fields", "ros2", "/sonar", "Range",
     "std_msgs/Header header\nuint8 radiation_type\n" + HEADER_DEFS, "min_range"),
    ("range-schema-renamed-fields", "ros2", "/sonar", "Range",
     "std_msgs/Header header\nuint8 kind\nfloat32 fov\nfloat32 lo\nfloat32 hi\nfloat32 r\n"
     + HEADER_DEFS, "min_range"),
    ("range-schema-no-header", "ros2", "/sonar", "Range",
     "uint8 radiation_type\nfloat32 field_of_view\nfloat32 min_range\nfloat32 max_range\n"
     "float32 range\n", "header"),
    ("odometry-schema-other", "ros2", "/odom", "Odometry", "float64 x\n", "header"),
    ("odometry-schema-no-pose", "ros2", "/odom", "Odometry",
     "std_msgs/Header header\nstring child_frame_id\n" + HEADER_DEFS, "pose"),
    ("tf-schema-other", "ros2", "/tf_static", "TFMessage", "int32 n\n", "transforms"),
    ("ros1-scan-schema-lacks-ranges", "ros1", "/scan", "LaserScan",
     "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n"
     "================================================================================\n"
     "MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n", "ranges"),
]:  # fmt: skip
    edited_mcap_case(_name, _base, f": message 1 of {_topic} ", f"no attribute '{_fragment}'",
                     schema=_schema_of(_type, _schema))  # fmt: skip


# ROS 1 bags


def bag_case(name: str, place: str, fragment: str, change: Callable[[bytearray], None]) -> None:
    def build(folder: Path) -> None:
        data = bytearray(bases()["bag"].read_bytes())
        change(data)
        (folder / "log.bag").write_bytes(bytes(data))

    case(f"bag-{name}", "bag", "log.bag", place, fragment)(build)


def _bag_index_of(data: bytearray, field: bytes) -> int:
    return bytes(data).index(field)


bag_case("truncated-half", ": byte ", "truncated",
         lambda d: d.__delitem__(slice(len(d) // 2, None)))  # fmt: skip
bag_case("truncated-header", ": byte ", "remain", lambda d: d.__delitem__(slice(40, None)))
bag_case(
    "version-line",
    ": byte 0: ",
    "not a ROS 1 bag of format 2.0",
    lambda d: d.__setitem__(slice(0, 13), b"#ROSBAG V1.2\n"),
)
bag_case(
    "index-pos-lie",
    ": byte 13: ",
    "index_pos",
    lambda d: struct.pack_into("<Q", d, _bag_index_of(d, b"index_pos=") + 10, 1 << 40),
)
bag_case(
    "chunk-count-lie",
    ": byte 13: ",
    "chunks",
    lambda d: struct.pack_into("<I", d, _bag_index_of(d, b"chunk_count=") + 12, 1 << 30),
)
bag_case(
    "conn-count-lie",
    ": byte 13: ",
    "connections",
    lambda d: struct.pack_into("<I", d, _bag_index_of(d, b"conn_count=") + 11, 1 << 30),
)
bag_case(
    "compression-unknown",
    ": byte ",
    "compression 'zzzz' unknown",
    lambda d: d.__setitem__(
        slice(
            _bag_index_of(d, b"compression=none") + 12, _bag_index_of(d, b"compression=none") + 16
        ),
        b"zzzz",
    ),
)


def _string_length_lie(data: bytearray) -> None:
    at = bytes(data).index(b"\x02\x00\x00\x00s0")  # the Range message's frame_id "s0"
    struct.pack_into("<I", data, at, 0x7FFFFFFF)


def _chunk_size_lie(data: bytearray) -> None:
    at = bytes(data).index(b"size=")
    struct.pack_into("<I", data, at + 5, struct.unpack_from("<I", data, at + 5)[0] + 1)


def _inner_record_lie(data: bytearray) -> None:
    # the header length of the first record inside the first chunk
    struct.pack_into("<I", data, _chunk_data_start(bytes(data)), 1 << 30)


def _chunk_data_start(data: bytes) -> int:
    pos = len(b"#ROSBAG V2.0\n")
    while True:
        (hlen,) = struct.unpack_from("<I", data, pos)
        header = data[pos + 4 : pos + 4 + hlen]
        if b"op=\x05" in header:
            return pos + 4 + hlen + 4
        (dlen,) = struct.unpack_from("<I", data, pos + 4 + hlen)
        pos += 8 + hlen + dlen


bag_case("message-string-length-lie", ": message ", "does not decode", _string_length_lie)
bag_case("chunk-size-lie", ": byte ", "its header says", _chunk_size_lie)
bag_case("chunk-inner-record-lie", ": byte ", "more than the chunk holds", _inner_record_lie)


# rosbag2 folders


def rosbag2_case(name: str, base: str, input_name: str, place: str, fragment: str,
                 change: Callable[[Path], None]) -> None:  # fmt: skip
    def build(folder: Path) -> None:
        shutil.copytree(bases()[base], folder / "bag")
        change(folder / "bag")

    case(f"rosbag2-{name}", "rosbag2", input_name, place, fragment)(build)


def _edit_text(name: str, old: str, new: str) -> Callable[[Path], None]:
    def change(bag: Path) -> None:
        path = bag / name
        path.write_text(path.read_text().replace(old, new, 1))

    return change


def _mcap_in(bag: Path) -> Path:
    return next(bag.glob("*.mcap"))


rosbag2_case("metadata-yaml-syntax", "sqlite", "bag/metadata.yaml", ":4: ", "not valid YAML",
             _edit_text("metadata.yaml", "rosbag2_bagfile_information:\n",
                        "rosbag2_bagfile_information:\n  [\n"))  # fmt: skip
rosbag2_case(
    "metadata-no-information",
    "sqlite",
    "bag/metadata.yaml",
    ": ",
    "KeyError",
    _edit_text("metadata.yaml", "rosbag2_bagfile_information", "something_else"),
)
rosbag2_case(
    "storage-unknown",
    "sqlite",
    "bag/metadata.yaml",
    ": ",
    "unknown rosbag2 storage",
    _edit_text("metadata.yaml", "storage_identifier: sqlite3", "storage_identifier: x"),
)
rosbag2_case("mcap-file-missing", "mcap-storage", "bag/metadata.yaml", ": ", "not in the folder",
             lambda bag: _mcap_in(bag).unlink())  # fmt: skip


def _damage_mcap_in(change: Callable[[bytearray], None]) -> Callable[[Path], None]:
    def apply(bag: Path) -> None:
        path = _mcap_in(bag)
        data = bytearray(path.read_bytes())
        change(data)
        path.write_bytes(bytes(data))

    return apply


def _mcap_storage_case(name: str, place: str, fragment: str,
                       change: Callable[[bytearray], None]) -> None:  # fmt: skip
    def build(folder: Path) -> None:
        shutil.copytree(bases()["mcap-storage"], folder / "bag")
        _damage_mcap_in(change)(folder / "bag")
        # the error names the damaged file inside the folder; the case's input is the folder
        (folder / "bag.input").write_text(_mcap_in(folder / "bag").name)

    case(f"rosbag2-{name}", "rosbag2", "bag/*.mcap", place, fragment)(build)


_mcap_storage_case("mcap-storage-truncated", ": byte ", "no valid footer",
                   lambda d: d.__delitem__(slice(len(d) // 2, None)))  # fmt: skip
_mcap_storage_case(
    "mcap-storage-record-length-lie",
    ": byte ",
    "claims",
    _pack(lambda d: _first(d, MESSAGE_INDEX)[0] + 1, "<Q", 1 << 40),
)


def _sqlite_damage(change: Callable[[Path], None], name: str, place: str, fragment: str) -> None:
    rosbag2_case(name, "sqlite", "bag", place, fragment, change)


def _db3(bag: Path) -> Path:
    return next(bag.glob("*.db3"))


def _truncate_db3(bag: Path) -> None:
    path = _db3(bag)
    path.write_bytes(path.read_bytes()[:2048])


def _garbage_db3(bag: Path) -> None:
    _db3(bag).write_bytes(b"this is not a database" * 100)


def _cdr_cut(bag: Path) -> None:
    import sqlite3

    with sqlite3.connect(_db3(bag)) as db:
        db.execute("UPDATE messages SET data = substr(data, 1, 6)")


_sqlite_damage(_truncate_db3, "db3-truncated", ": ", "rosbag2")
_sqlite_damage(_garbage_db3, "db3-not-a-database", ": ", "rosbag2")
_sqlite_damage(_cdr_cut, "db3-messages-cut", ": message 1 ", "does not decode")


# issue 21: metadata.yaml that contradicts the files (compression, storage): one line, the file


def _zstd(data: bytes) -> bytes:
    from backports import zstd  # rosbags' own zstd (compression.zstd from Python 3.14)

    return bytes(zstd.compress(data))


def _compress_file(bag: Path) -> None:
    path = next(p for p in bag.iterdir() if p.name != "metadata.yaml")
    path.write_bytes(_zstd(path.read_bytes()))


def _metadata_case(
    name: str, base: str, names_file: bool, place: str, fragment: str,
    edits: dict[str, str], also: Callable[[Path], None] | None = None,
) -> None:  # fmt: skip
    """A rosbag2 folder whose metadata says ``edits`` (key: new value); the error names the
    data file (``names_file``) or metadata.yaml."""

    def build(folder: Path) -> None:
        shutil.copytree(bases()[base], folder / "bag")
        meta = folder / "bag" / "metadata.yaml"
        lines = meta.read_text().splitlines(keepends=True)
        for key, value in edits.items():
            lines = [f"  {key}: {value}\n" if x.startswith(f"  {key}:") else x for x in lines]
        meta.write_text("".join(lines))
        if also is not None:
            also(folder / "bag")
        data = next(p for p in (folder / "bag").iterdir() if p.name != "metadata.yaml")
        (folder / "bag.input").write_text(data.name if names_file else "metadata.yaml")

    case(f"rosbag2-{name}", "rosbag2", "bag/*", place, fragment)(build)


ZSTD = {"compression_format": "zstd"}
for _name, _base, _file, _place, _fragment, _edits, _also in [
    ("zstd-messages-over-plain-sqlite", "sqlite", True, ": message 1 of /tf_static: ",
     "not zstd-compressed", {**ZSTD, "compression_mode": "MESSAGE"}, None),
    ("zstd-file-over-plain-sqlite", "sqlite", True, ": ",
     "but this is an sqlite3 database, not compressed", {**ZSTD, "compression_mode": "FILE"},
     None),
    ("plain-over-zstd-file", "sqlite", True, ": ", "no compression, but this is zstd", {},
     _compress_file),
    ("lz4-file", "sqlite", False, ": ", "compression_format 'lz4'",
     {"compression_format": "lz4", "compression_mode": "FILE"}, None),
    ("compression-mode-unknown", "sqlite", False, ": ", "unknown compression_mode 'sometimes'",
     {**ZSTD, "compression_mode": "sometimes"}, None),
    ("mcap-storage-over-sqlite", "sqlite", True, ": ", "says storage mcap, but this is an sqlite3",
     {"storage_identifier": "mcap"}, None),
    ("sqlite-storage-over-mcap", "mcap-storage", True, ": ",
     "says storage sqlite3, but this is an MCAP file", {"storage_identifier": "sqlite3"}, None),
    ("zstd-messages-over-mcap", "mcap-storage", False, ": ", "message compression over MCAP",
     {**ZSTD, "compression_mode": "MESSAGE"}, None),
    ("zstd-file-over-mcap", "mcap-storage", False, ": ", "zstd-compressed MCAP storage files",
     {**ZSTD, "compression_mode": "FILE"}, None),
    ("zstd-file-over-zstd-mcap", "mcap-storage", False, ": ", "zstd-compressed MCAP storage",
     {**ZSTD, "compression_mode": "FILE"}, _compress_file),
]:  # fmt: skip
    _metadata_case(_name, _base, _file, _place, _fragment, _edits, _also)


# issue 21: a zero-norm or non-finite quaternion (odometry, TF, a static mount) is no rotation:
# refused with the message's topic and log time, in every container (bulk and one by one)

QUATERNIONS = {
    "zero": ({"x": 0.0, "y": 0.0, "z": 0.0, "w": 0.0}, "has zero norm"),
    "nan": ({"x": 0.0, "y": 0.0, "z": float("nan"), "w": 1.0}, "is not finite"),
    "inf": ({"x": 0.0, "y": 0.0, "z": 0.0, "w": float("inf")}, "is not finite"),
}
#: where the bad rotation is: (topic, log time of the bad message, what the error says)
ROTATION_PLACES = {
    "odometry": ("/odom", "1.300000000", "orientation quaternion"),
    "tf": ("/tf", "1.300000000", "transform odom -> base_link: quaternion"),
    "static-mount": ("/tf_static", "1.000000000", "transform base_link -> s0: quaternion"),
}


def _rotation_recording(path: Path, where: str, q: dict[str, float]) -> Path:
    from tests.readers.mcap_helpers import Recording, S, odometry, sonar_range, static_tf

    with Recording(path) as rec:
        mount = rec.transform(0, "base_link", "s0", 0.0, 0.0, 0.0)
        if where == "static-mount":
            mount["transform"]["rotation"] = q
        static_tf(rec, mount)
        for k in range(11):
            ns = S + k * S // 10
            if where == "tf":
                t = rec.transform(ns, "odom", "base_link", 0.1 * k, 0.0, 0.0)
                if k == 3:
                    t["transform"]["rotation"] = q
                rec.write("/tf", "tf2_msgs/TFMessage", ns, {"transforms": [t]})
                continue
            msg = odometry(rec, ns, 0.1 * k, 0.0, 0.0)
            if k == 3 and where == "odometry":
                msg["pose"]["pose"]["orientation"] = q
            rec.write("/odom", "nav_msgs/Odometry", ns, msg)
        rec.write("/sonar", "sensor_msgs/Range", S, sonar_range(rec, S, "s0", 1.0))
    return path


def _rotation_case(container: str, where: str, kind: str) -> None:
    from tests.readers.bag_helpers import write_bag, write_rosbag2

    topic, at, what = ROTATION_PLACES[where]
    q, problem = QUATERNIONS[kind]
    name = {"mcap": "log.mcap", "bag": "log.bag", "rosbag2": "bag"}[container]

    def build(folder: Path) -> None:
        if container == "mcap":
            _rotation_recording(folder / name, where, q)
            return
        source = _rotation_recording(folder / "source.mcap", where, q)
        if container == "bag":
            write_bag(source, folder / name)
        else:
            write_rosbag2(source, folder / name)
        source.unlink()

    place = f": {topic} at log time {at} s: "
    fragment = f"{what} ({', '.join(f'{v:g}' for v in q.values())}) {problem}"
    case(f"{container}-{where}-quaternion-{kind}", container, name, place, fragment)(build)


for _container in ("mcap", "bag", "rosbag2"):
    for _where in ROTATION_PLACES:
        for _kind in QUATERNIONS:
            _rotation_case(_container, _where, _kind)


# issue 21: the beam-count limit (MAX_LASER_SAMPLES) in every reader of scans, not only in
# robot descriptions and ARIA: CARMEN's laser lines, LaserScan messages of every container

BEAMS = 100_001
_POSE9 = "0.0 0.0 0.0"
for _name, _line in [
    ("flaser-too-many-beams",
     f"FLASER {BEAMS} " + "1 " * BEAMS + f"{_POSE9} {_POSE9} 1.3 host 1.3\n"),
    ("robotlaser-too-many-beams",
     f"ROBOTLASER1 0 -1.5 3.1 0.00003 80 0.01 0 {BEAMS} " + "1 " * BEAMS
     + f"0 {_POSE9} {_POSE9} 0 0 0 0 0 1.3 host 1.3\n"),
]:  # fmt: skip
    text_case(f"carmen-{_name}", "carmen", "run.log", carmen_text({10: _line}), 10,
              "MAX_LASER_SAMPLES")  # fmt: skip


def _wide_scan_recording(path: Path, ros: int = 2) -> Path:
    from tests.readers.mcap_helpers import Recording, S, drive, static_tf

    with Recording(path, ros=ros) as rec:
        static_tf(rec, rec.transform(0, "base_link", "laser", 0.0, 0.0, 0.0))
        drive(rec)
        scan = {
            "header": rec.header(S, "laser"), "angle_min": -1.5, "angle_max": 1.5,
            "angle_increment": 3.0 / (BEAMS - 1), "range_min": 0.1, "range_max": 5.0,
            "ranges": [1.0] * BEAMS, "intensities": [],
        }  # fmt: skip
        rec.write("/scan", "sensor_msgs/LaserScan", S, scan)
    return path


def _wide_scan_case(container: str) -> None:
    from tests.readers.bag_helpers import write_bag, write_rosbag2

    name = {"mcap": "log.mcap", "ros1-mcap": "log.mcap", "bag": "log.bag", "rosbag2": "bag"}

    def build(folder: Path) -> None:
        target = folder / name[container]
        if container in ("mcap", "ros1-mcap"):
            _wide_scan_recording(target, 1 if container == "ros1-mcap" else 2)
            return
        source = _wide_scan_recording(folder / "source.mcap")
        (write_bag if container == "bag" else write_rosbag2)(source, target)
        source.unlink()

    reader = "mcap" if container == "ros1-mcap" else container
    place = ": /scan at log time 1.000000000 s: laser 'laser': "
    case(f"{container}-scan-too-many-beams", reader, name[container], place,
         f"a scan of {BEAMS:,} beams")(build)  # fmt: skip


for _container in ("mcap", "ros1-mcap", "bag", "rosbag2"):
    _wide_scan_case(_container)


def good_inputs(folder: Path) -> list[tuple[str, Path]]:
    """The unbroken inputs every case starts from, as (command, path): each must succeed, so
    that a case fails for the one change its name says."""
    files = {
        "log.csv": csv_text(), "log.2d": aria_text(), "run.log": carmen_text(),
        "robot.yaml": robot_text(), "robot.p": P_HEAD + P_RING,
    }  # fmt: skip
    out: list[tuple[str, Path]] = []
    for name, text in files.items():
        (folder / name).write_text(text, encoding="latin-1" if name.endswith(".2d") else "utf-8")
        out.append(("robot" if name.startswith("robot") else "build", folder / name))
    world_case("good", WORLD_YAML, None, "")
    _, build = _CASES.pop()
    build(folder)
    out.append(("world", folder / "world.yaml"))
    out += [("build", path) for path in bases().values()]
    return out


def all_cases() -> list[Case]:
    return [c for c, _ in _CASES]


def build_case(name: str, folder: Path) -> Path:
    """Write case ``name`` into ``folder`` (created); returns the input path gridmap is given
    (for ``bag/*`` cases, the rosbag2 folder; the error names the file inside)."""
    for c, build in _CASES:
        if c.name == name:
            folder.mkdir(parents=True, exist_ok=True)
            build(folder)
            if c.command == "world":
                return folder / "world.yaml"
            return folder / "bag" if c.input.startswith("bag/*") else folder / c.input
    raise KeyError(name)


def named_path(c: Case, folder: Path) -> Path:
    """The file the error must name."""
    if c.input.startswith("bag/*"):
        return folder / "bag" / (folder / "bag.input").read_text()
    return folder / c.input


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    out = Path(argv[0])
    for c in all_cases():
        build_case(c.name, out / c.name)
    (out / "cases.json").write_text(json.dumps([asdict(c) for c in all_cases()], indent=1))
    print(f"{len(_CASES)} cases written to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
