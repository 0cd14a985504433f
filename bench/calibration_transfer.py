"""Does a calibration transfer? Predicted against actual error of the corrected odometry.

For each CARMEN log and half (cut by time, as ``bench/carmen_experiment.py`` cuts them): the
odometry error is calibrated on one half, the other half's odometry is corrected by its biases
and placed at that half's first reference pose, and its actual error against the reference
(position, heading) is printed next to what the random part of the calibration predicts
(``propagate``'s standard deviation), at several distances driven along the half, and the
root mean square of both over the half. The calibration half itself is shown too (``self``),
to see whether the model fits the data it was fitted on at the lengths the map uses.

    .venv/bin/python bench/calibration_transfer.py            # every log
    .venv/bin/python bench/calibration_transfer.py --logs aces
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.poses.calibration.calibrate import Calibration, calibrate_tracks
from gridmap_cli.poses.calibration.windows import truth_at_odometry
from gridmap_cli.poses.odometry_error import OdometryError, correct_track, travelled
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise, propagate
from gridmap_cli.readers import read_log
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import robot_from_log

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "carmen"
LOGS = ("intel", "aces", "freiburg-079")
#: Fractions of a half's distance at which the errors are printed.
AT = (0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0)


def halves(path: Path) -> dict[str, RangeLog]:
    data = read_log(path)
    robot = robot_from_log(path, data.metadata)
    stamps = data.poses.stamp_ns
    first = min(int(stamps[0]), int(data.readings.stamp_ns[0]))
    mid = 0.5 * (int(stamps[-1]) - first) / 1e9
    out = {}
    for name, (a, b) in {"first": (None, mid), "second": (mid, None)}.items():
        sel = Selection.parse(
            (), None if a is None else f"{a:.3f}", None if b is None else f"{b:.3f}"
        )
        out[name] = apply_selection(data, sel, robot).log
    return out


def placed(odometry: PoseTrack, truth: PoseTrack) -> PoseTrack:
    """``odometry`` moved rigidly so that its first pose is the truth's."""
    rot = truth.theta_rad[0] - odometry.theta_rad[0]
    c, s = math.cos(rot), math.sin(rot)
    ex, ey = odometry.x_m - odometry.x_m[0], odometry.y_m - odometry.y_m[0]
    return PoseTrack(
        odometry.stamp_ns,
        truth.x_m[0] + c * ex - s * ey,
        truth.y_m[0] + s * ex + c * ey,
        odometry.theta_rad + rot,
    )


def compare(log: RangeLog, model: OdometryError) -> list[str]:
    odometry, truth = truth_at_odometry(log)
    corrected = placed(correct_track(odometry, model), truth)
    unc = propagate(corrected, StepNoise.of(model.random_part()))
    cov = unc.at(corrected.stamp_ns)
    ex, ey = corrected.x_m - truth.x_m, corrected.y_m - truth.y_m
    eh = wrap_angle(corrected.theta_rad - truth.theta_rad)
    dist, _ = travelled(corrected)
    pos_var = cov[:, 0, 0] + cov[:, 1, 1]
    lines = []
    for f in AT:
        i = min(int(np.searchsorted(dist, f * dist[-1])), len(dist) - 1)
        lines.append(
            f"    {dist[i]:7.1f} m  position {math.hypot(ex[i], ey[i]):6.2f} m / sd "
            f"{math.sqrt(pos_var[i]):6.2f} m   heading {math.degrees(abs(eh[i])):6.2f} / sd "
            f"{math.degrees(math.sqrt(cov[i, 2, 2])):6.2f} deg"
        )
    lines.append(
        f"    over the half: rms position error {float(np.sqrt(np.mean(ex**2 + ey**2))):.2f} m, "
        f"predicted rms sd {float(np.sqrt(np.mean(pos_var))):.2f} m"
    )
    return lines


def coefficients(cal: Calibration) -> str:
    m = cal.model
    return (
        f"a {m.distance_scale_bias:+.4f} u {m.turn_scale_bias:+.4f} "
        f"c {m.heading_drift_bias_rad_per_m:+.5f} | q_a {m.range_m_per_sqrt_m:.4f} "
        f"q_t {m.bearing_rad_per_sqrt_rad:.4f} q_h {m.heading_rad_per_sqrt_m:.4f} | jitter "
        f"{cal.jitter_m * 100:.1f} cm {math.degrees(cal.jitter_rad):.2f} deg"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(LOGS))
    args = parser.parse_args(argv)
    for name in args.logs.split(","):
        parts = halves(DATA / f"{name}-corrected.log.gz")
        cals = {}
        for half, log in parts.items():
            cal = calibrate_tracks(*truth_at_odometry(log))
            assert cal is not None
            cals[half] = cal
            print(f"{name} {half} half calibration: {coefficients(cal)}")
        for half, other in (("first", "second"), ("second", "first")):
            for source in (other, half):
                tag = "other half's" if source == other else "self"
                print(f"{name} {half} half, {tag} calibration ({source}):")
                print("\n".join(compare(parts[half], cals[source].model)))


if __name__ == "__main__":
    main()
