"""Convert the real 8-sonar log of ``../shared/data/sonar`` into a gridmap CSV and robot file.

The log (udacity/RoboND-OccupancyGridMappingAlgorithm, MIT) is two text files sharing their
stamps: ``poses.txt`` holds ``t_ms x_mm y_mm theta`` with theta in tenths of a degree (wrapping
at 3600) and ``measurement.txt`` holds ``t_ms r0 .. r7``, eight sonar ranges in millimetres, 5110
meaning no echo. The sensor layout is not in the data; a Pioneer 3-DX front ring read from right
to left (``r0`` is the ring's rightmost transducer, ARIA's ``sonar7`` at -90 degrees; ``r7`` its
leftmost, ``sonar0`` at +90 degrees) gives straight corridor walls, the reverse order does not
(``--reverse`` writes that order, to compare).

The robot file is the Pioneer 3-DX preset's front ring with the log's own range limit: the log
reports readings up to 5.1 m and writes 5110 mm for no echo, so the limit is 5.11 m, not the
ARIA ``.p`` file's 4.335 m (which would turn the log's echoes beyond it into no-echo readings).

    .venv/bin/python samples/udacity_sonar.py ../shared/data/sonar out/sonar
    gridmap build out/sonar/sonar.csv -o out/sonar/standard.png
    gridmap build out/sonar/sonar.csv -o out/sonar/error-aware.png --mode error-aware \
        --odometry-coefficient range_m_per_sqrt_m=0.02 \
        --odometry-coefficient bearing_rad_per_sqrt_rad=0.02 \
        --odometry-coefficient heading_drift_rad_per_m=0.002

The log has no reference track to calibrate against, so the error-aware map takes generic
random walks (``ERROR_AWARE_ARGS``; docs/odometry-error.md names them), not a calibration.
``--figure PATH`` also builds both maps (scale mode) and writes them side by side, as
docs/sensor-model.md shows them.

The product needs no reader for this layout: this script is the documented conversion, and
``tests/test_real_sonar.py`` runs it.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from gridmap_cli.robot import load_robot

#: The log's own value for "no echo", in millimetres.
NO_ECHO_MM = 5110
#: ``gridmap build`` arguments of the error-aware map: generic random walks and a small heading
#: drift, spread (not corrected), since the log has no reference to calibrate them on.
ERROR_AWARE_ARGS = (
    "--mode", "error-aware",
    "--odometry-coefficient", "range_m_per_sqrt_m=0.02",
    "--odometry-coefficient", "bearing_rad_per_sqrt_rad=0.02",
    "--odometry-coefficient", "heading_drift_rad_per_m=0.002",
)  # fmt: skip
#: ARIA's names for the front ring, from the log's first column (rightmost) to its last.
RIGHT_TO_LEFT = tuple(f"sonar{k}" for k in range(7, -1, -1))


def convert(source: Path, out_dir: Path, *, reverse: bool = False) -> tuple[Path, Path]:
    """Write ``out_dir/sonar.csv`` and ``out_dir/sonar-robot.yaml`` from the log in ``source``;
    returns their paths. ``reverse``: read the columns left to right instead."""
    poses = np.loadtxt(source / "poses.txt", dtype=np.int64, ndmin=2)
    ranges = np.loadtxt(source / "measurement.txt", dtype=np.int64, ndmin=2)
    if poses.shape[1] != 4 or ranges.shape[1] != 9:
        raise ValueError(f"{source}: expected 4 pose columns and 9 measurement columns")
    if len(poses) != len(ranges) or not np.array_equal(poses[:, 0], ranges[:, 0]):
        raise ValueError(f"{source}: poses.txt and measurement.txt do not share their stamps")
    names = tuple(reversed(RIGHT_TO_LEFT)) if reverse else RIGHT_TO_LEFT
    out_dir.mkdir(parents=True, exist_ok=True)
    robot_path = out_dir / "sonar-robot.yaml"
    robot_path.write_text(_robot_yaml())
    csv_path = out_dir / "sonar.csv"
    t0 = poses[0, 0]
    lines = ["# gridmap-csv: 1", f"# robot: {robot_path.name}",
             "time,x,y,theta," + ",".join(names)]  # fmt: skip
    for pose, reading in zip(poses, ranges, strict=True):
        theta = math.remainder(math.radians(pose[3] / 10.0), 2 * math.pi)
        fields = [f"{(pose[0] - t0) / 1000:.3f}", f"{pose[1] / 1000:.3f}",
                  f"{pose[2] / 1000:.3f}", f"{theta:.6f}"]  # fmt: skip
        fields += [f"{r / 1000:.3f}" for r in reading[1:]]
        lines.append(",".join(fields))
    csv_path.write_text("\n".join(lines) + "\n")
    return csv_path, robot_path


def _robot_yaml() -> str:
    """The Pioneer 3-DX front ring, as the preset gives it, with the log's range limit."""
    preset = load_robot("p3dx").by_name()
    rows = []
    for name in RIGHT_TO_LEFT:
        s = preset[name]
        rows.append(
            f"  - {{name: {name}, x_m: {s.x_m:.3f}, y_m: {s.y_m:.3f}, "
            f"yaw_deg: {math.degrees(s.yaw_rad):.0f}}}"
        )
    first = preset[RIGHT_TO_LEFT[0]]
    return "\n".join(
        [
            "# The Pioneer 3-DX front ring (gridmap's p3dx preset) with the udacity log's range",
            "# limit: it writes 5110 mm for no echo (samples/udacity_sonar.py).",
            "gridmap-robot: 1",
            "name: udacity-sonar",
            "defaults:",
            "  kind: sonar",
            f"  beam_width_deg: {math.degrees(first.beam_width_rad):.1f}",
            f"  min_range_m: {first.min_range_m}",
            f"  max_range_m: {NO_ECHO_MM / 1000}",
            "sensors:",
            *rows,
            "",
        ]
    )


def figure(csv_path: Path, out: Path) -> None:
    """Build the standard and error-aware maps of ``csv_path`` (scale mode) beside it and write
    them side by side to ``out``."""
    from PIL import Image

    from gridmap_cli.cli import cli

    images = []
    for name, extra in (("standard", ()), ("error-aware", ERROR_AWARE_ARGS)):
        image = csv_path.with_name(f"{name}.png")
        args = ["build", str(csv_path), "-o", str(image), "--map-mode", "scale", "--force", "-q"]
        cli.main([*args, *extra], standalone_mode=False)
        images.append(Image.open(image).convert("RGB"))
    gap = 8
    sheet = Image.new(
        "RGB", (sum(i.width for i in images) + gap, max(i.height for i in images)), "white"
    )
    sheet.paste(images[0], (0, 0))
    sheet.paste(images[1], (images[0].width + gap, 0))
    sheet.save(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("source", type=Path, help="folder holding poses.txt and measurement.txt")
    parser.add_argument("out_dir", type=Path, help="folder to write sonar.csv and its robot file")
    parser.add_argument("--reverse", action="store_true", help="the columns left to right")
    parser.add_argument("--figure", type=Path, help="also write both maps side by side here")
    args = parser.parse_args()
    csv_path, robot_path = convert(args.source, args.out_dir, reverse=args.reverse)
    print(f"wrote {csv_path} and {robot_path}")
    if args.figure is not None:
        figure(csv_path, args.figure)
        print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
