"""Where a calibration's turn scale comes from: the windows' heading errors by window length,
with the reference interpolated at the odometry's stamps (what ``gridmap calibrate`` compares)
and with the odometry at the reference's own stamps.

A CARMEN log's reference (its corrected poses, one per laser scan) is much sparser than its
odometry: Intel has 910 reference poses, a median 3.3 s apart, for 14,541 odometry poses. Taken
at the odometry's stamps the reference is a straight line between two of its poses, and a
window that ends in a turn compares that line with the odometry's measured turn. For each log
and window length (1 to 50 times 1 m / 90 degrees, the calibration's ladder) this prints the
least-squares turn scale and heading drift (``e_h = u t + c d``) both ways: a constant turn scale
is the same at every length; the interpolation's error does not grow with the window and so
shrinks in the shorter windows' favour as they lengthen. docs/odometry-error.md, "Intel's turn
scale", has the figures.

    .venv/bin/python bench/reference_stamps.py            # the six CARMEN logs
    .venv/bin/python bench/reference_stamps.py --logs intel
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.calibration.calibrate import JITTER_LADDER
from gridmap_cli.poses.calibration.windows import (
    DEFAULT_WINDOW_M,
    DEFAULT_WINDOW_RAD,
    begin_indices,
    compare_windows,
    truth_at_odometry,
)
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.readers import read_log
from gridmap_cli.records import PoseTrack, RangeLog

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "carmen"
LOGS = ("intel", "aces", "freiburg-079", "seattle", "acapulco", "belgioioso")


def odometry_at_reference(log: RangeLog) -> tuple[PoseTrack, PoseTrack]:
    """The odometry at the reference's stamps (its heading interpolated on the sum of its own
    wrapped increments, so that a turn between two reference poses is not taken the short way
    round), and the reference there."""
    odo, truth = log.poses, log.require_truth("the bench compares the odometry against it")
    x, y, _, valid = interpolate_pose(odo, truth.stamp_ns)
    turned = np.concatenate([[0.0], np.cumsum(wrap_angle(np.diff(odo.theta_rad)))])
    heading = odo.theta_rad[0] + np.interp(truth.stamp_ns, odo.stamp_ns, turned)
    stamps = truth.stamp_ns[valid]
    return (
        PoseTrack(stamps, x[valid], y[valid], wrap_angle(heading[valid])),
        PoseTrack(stamps, truth.x_m[valid], truth.y_m[valid], truth.theta_rad[valid]),
    )


def by_length(odometry: PoseTrack, reference: PoseTrack) -> list[tuple[float, float, float, int]]:
    """(length, turn scale, heading drift, windows) for each rung of the calibration's ladder."""
    main = compare_windows(odometry, reference)
    begins = begin_indices(odometry, reference, main)
    out = []
    for k in JITTER_LADDER:
        w = compare_windows(
            odometry, reference, DEFAULT_WINDOW_M * k, DEFAULT_WINDOW_RAD * k,
            DEFAULT_WINDOW_M, DEFAULT_WINDOW_RAD, begins,
        )  # fmt: skip
        if len(w) < 3:
            continue
        design = np.column_stack([w.turned_rad, w.driven_m])
        (u, c), *_ = np.linalg.lstsq(design, w.heading_error_rad, rcond=None)
        out.append((k, float(u), float(c), len(w)))
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(LOGS), help="comma-separated")
    args = parser.parse_args(argv)
    for name in args.logs.split(","):
        log = read_log(DATA / f"{name}-corrected.log.gz")
        truth = log.require_truth("the bench compares the odometry against it")
        step = lambda t: float(np.median(np.diff(t.stamp_ns))) / 1e9  # noqa: E731
        print(
            f"{name}: {len(log.poses)} odometry poses ({step(log.poses):.2f} s apart), "
            f"{len(truth)} reference poses ({step(truth):.2f} s apart, median)"
        )
        for label, tracks in (
            ("reference at the odometry's stamps", truth_at_odometry(log)),
            ("odometry at the reference's stamps", odometry_at_reference(log)),
        ):
            rows = by_length(*tracks)
            cells = " ".join(f"{k:g}:{u:+.4f}" for k, u, _, _ in rows)
            print(f"  {label}: turn scale by window length {cells}")


if __name__ == "__main__":
    main()
