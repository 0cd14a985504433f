"""``gridmap calibrate``: the odometry error model, from a log's reference track or, for a laser
log without one, from gridmap's own corrected poses (``--reference scan-matched`` or ``slam``)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING

import click

from gridmap_cli import __version__
from gridmap_cli.cli.common import (
    STDIO,
    check_input,
    check_output_folder,
    force_option,
    format_option,
    handle_errors,
    json_option,
    json_text,
    quiet_option,
    read_input,
    selection_options,
    warn,
)
from gridmap_cli.cli.progress import StageBars, reading
from gridmap_cli.errors import InputFileError, UsageError
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.poses.sources import (
    ODOMETRY_SOURCE,
    SOURCES,
    PoseSettings,
    pose_source,
)
from gridmap_cli.readers import STDIN_NAME
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import RangeLog
from gridmap_cli.writers import check_output

if TYPE_CHECKING:
    # scipy.ndimage (0.3 s) comes with it: imported when the command runs
    from gridmap_cli.poses.calibration.calibrate import Calibration
    from gridmap_cli.robot import RangeSensor, RobotDescription

#: calibrate.JITTER_LADDER and robust_fit.OUTLIER_SIGMA, kept here so that --help stays fast
#: (tests/test_calibrate.py checks they agree)
JITTER_LADDER = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0)
OUTLIER_SIGMA = 3.0

#: What calibrate compares the track with (--reference): the log's own, or a correction the
#: laser makes.
REFERENCES = ("truth", *(s.name for s in SOURCES if "laser" in s.needs))


@click.command()
@click.argument("log", type=click.Path(path_type=Path, readable=False))
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path, readable=False),
    help="Odometry-error YAML to write (what build takes); default: print only.",
)
@format_option
@click.option(
    "--window",
    "window_m",
    type=float,
    default=1.0,
    show_default=True,
    help="Metres of travel per comparison window.",
)
@click.option(
    "--window-turn",
    "window_deg",
    type=float,
    default=90.0,
    show_default=True,
    help="Degrees of turning that also close a window (for turns on the spot).",
)
@click.option(
    "--sonar-error",
    type=float,
    default=0.01,
    show_default=True,
    help="The sonar's relative range error k to write into the file (0.01 = 1 %).",
)
@click.option(
    "--pose",
    type=click.Choice([s.name for s in SOURCES if s.needs and "reference" not in s.needs]),
    default=ODOMETRY_SOURCE,
    show_default=True,
    help="The track to calibrate against the reference: the odometry, or the odometry corrected "
    "by the laser (its residual drift, for error-aware maps built with --pose scan-matched), or "
    "the pose graph's track with loop closures (its residual drift: how far a --pose slam map "
    "can be trusted).",
)
@click.option(
    "--reference",
    type=click.Choice(REFERENCES),
    default="truth",
    show_default=True,
    help="What the track is compared with: the log's own reference (ground truth, a SLAM "
    "track), or, for a laser log without one, the odometry corrected by scan matching "
    "(scan-matched) or by the pose graph with loop closures (slam).",
)
@click.option(
    "--robot",
    help="--pose scan-matched, --reference scan-matched or slam: robot preset, YAML or .p file "
    "with the laser's mounting; default: the log's own.",
)
@selection_options(sensors=False)
@force_option("Overwrite an existing output.")
@json_option("Print the figures as JSON on stdout.")
@quiet_option("No table on stdout (with -o: just write).")
@handle_errors
def calibrate(
    log: Path,
    output: Path | None,
    log_format: str | None,
    window_m: float,
    window_deg: float,
    sonar_error: float,
    pose: str,
    reference: str,
    robot: str | None,
    start: str | None,
    end: str | None,
    force: bool,
    as_json: bool,
    quiet: bool,
) -> None:
    """Estimate the odometry-error coefficients of LOG against a reference track.

    The reference is LOG's own (CSV true_x/true_y/true_theta, ARIA robotGlobal, CARMEN's
    corrected poses, a ROS reference topic), or with --reference scan-matched or slam the
    laser's correction of the odometry. Odometry and reference are compared over windows of
    travel of several lengths; see docs/odometry-error.md.
    """
    from gridmap_cli.poses.calibration.calibrate import calibrate as calibrate_log
    from gridmap_cli.poses.odometry_error import save_odometry_error

    if not (window_m > 0.0 and math.isfinite(window_m)):
        raise UsageError(f"--window must be a positive number of metres, got {window_m}")
    if not (window_deg > 0.0 and math.isfinite(window_deg)):
        raise UsageError(f"--window-turn must be a positive number of degrees, got {window_deg}")
    if not (sonar_error >= 0.0 and math.isfinite(sonar_error)):
        raise UsageError(f"--sonar-error must be a finite number >= 0, got {sonar_error}")
    corrected = "odometry" not in pose_source(pose).needs  # not the robot's own odometry
    if corrected and reference != "truth":
        raise UsageError(
            f"--pose {pose} --reference {reference}: the corrected track would be compared "
            "with a correction of itself; calibrate the odometry (--pose odometry) against it"
        )
    selection = Selection.parse((), start, end)
    check_input(log)
    if output is not None:
        check_output(output, force)
        check_output_folder(output)
    laser = corrected or reference != "truth"
    with reading(log.name, quiet):  # the tracks alone unless a laser corrects one
        data = read_input([log], log_format, ReadOptions(poses_only=not laser))
    data = apply_selection(data, selection, None, need_readings=laser).log
    if reference == "truth" and data.truth is None:
        _no_reference(log, data, robot)
    if corrected:
        data = _corrected(log, data, robot, quiet, pose)
    elif reference != "truth":
        data = _own_reference(log, data, robot, reference, quiet)
    result = calibrate_log(data, window_m, math.radians(window_deg), sonar_error)
    if output is not None:
        save_odometry_error(
            result.model,
            output,
            comments=[
                f"gridmap {__version__} calibrate {log.name}"
                + (f" --pose {pose}" if corrected else "")
                + (f" --reference {reference}" if reference != "truth" else "")
                + f": {result.windows} windows of "
                f"{window_m:g} m or {window_deg:g} deg, {result.driven_m:.1f} m driven, "
                f"{math.degrees(result.turned_rad):.0f} deg turned",
            ],
        )
    if as_json:
        doc = {"log": str(log), "output": str(output) if output else None, **result.as_dict()}
        click.echo(json_text(doc))
    elif not quiet:
        click.echo(_calibration_table(STDIN_NAME if log == STDIO else str(log), result, output))


def sensors_for_log(data: RangeLog, robot: RobotDescription | None) -> tuple[RangeSensor, ...]:
    from gridmap_cli.poses.sync import sensors_for_log as sensors

    return sensors(data, robot)


def _robot(path: Path, data: RangeLog, robot: str | None) -> RobotDescription | None:
    from gridmap_cli.robot import load_robot, robot_from_log

    return load_robot(robot) if robot else robot_from_log(path, data.metadata)


def _no_reference(path: Path, data: RangeLog, robot: str | None) -> None:
    """Raise the error of a log without a reference track: what else to do, if it has a laser."""
    from gridmap_cli.errors import GridmapError

    try:
        kinds = {s.kind for s in sensors_for_log(data, _robot(path, data, robot))}
    except GridmapError:  # sensors the log does not describe: no laser it could match
        kinds = set()
    if "laser" in kinds:
        data.require_truth(
            "calibrate compares the odometry against it; --reference scan-matched or slam "
            "calibrates against the laser's correction of the odometry instead"
        )
    raise InputFileError(
        data.source,
        "the log has neither a reference track (ground truth, a SLAM track) nor a laser to "
        "make one (--reference scan-matched): nothing to calibrate the odometry against",
    )


def _own_reference(
    path: Path, data: RangeLog, robot: str | None, reference: str, quiet: bool
) -> RangeLog:
    """The log with its reference replaced by gridmap's own correction of its odometry, with
    the warnings of the correction (a reference that failed its checks calibrates nothing)."""
    from gridmap_cli.poses.correction.scan_match import NoLaserError

    description = _robot(path, data, robot)
    try:
        posed = pose_source(reference).run(data, description)
    except NoLaserError as exc:
        kinds = sorted({s.kind for s in sensors_for_log(data, description)}) or ["none"]
        raise NoLaserError(
            f"{data.source}: --reference {reference} corrects the odometry with laser scans, "
            f"and the log has none (its range sensors: {', '.join(kinds)}); calibrate needs a "
            "reference track or a laser"
        ) from exc
    warn(posed.warnings, quiet)
    return dataclasses.replace(data, truth=posed.log.poses)


def _corrected(path: Path, data: RangeLog, robot: str | None, quiet: bool, pose: str) -> RangeLog:
    """The log with its odometry replaced by the corrected track, the track whose residual
    drift against the reference is then calibrated: the scan matcher's at its scans, the
    pose graph's at the odometry's stamps."""
    description = _robot(path, data, robot)
    with StageBars(quiet) as bars:
        posed = pose_source(pose).run(data, description, PoseSettings(progress=bars))
    warn(posed.warnings, quiet)
    track = posed.log.poses
    if posed.slam is None and posed.match is not None:
        track = posed.match.track
    return dataclasses.replace(data, poses=track, odometry_missing=None)


def _coefficient_rows(c: Calibration) -> list[tuple[str, str, str]]:
    """Each coefficient: what it is, the odometry's error by it, its key in the file."""
    m = c.model

    def maybe(ok: bool, text: str) -> str:
        return text if ok else "not estimated"

    return [
        (
            "distance scale error",
            maybe(c.distance_estimated, f"{100 * c.scale_error:+.2f} % of distance"),
            "distance_scale_bias",
        ),
        (
            "distance random walk",
            maybe(c.distance_estimated, f"{100 * m.range_m_per_sqrt_m:.2f} cm after 1 m"),
            "range_m_per_sqrt_m",
        ),
        (
            "turn scale error",
            maybe(c.turn_estimated, f"{100 * c.turn_scale_error:+.2f} % of rotation"),
            "turn_scale_bias",
        ),
        (
            "turn random walk",
            maybe(
                c.turn_estimated,
                f"{math.degrees(m.bearing_rad_per_sqrt_rad):.2f} deg after 1 rad",
            ),
            "bearing_rad_per_sqrt_rad",
        ),
        (
            "heading drift",
            maybe(c.drift_estimated, f"{math.degrees(c.heading_drift_rad_per_m):+.3f} deg/m"),
            "heading_drift_bias_rad_per_m",
        ),
        (
            "heading random walk",
            maybe(
                c.drift_estimated,
                f"{math.degrees(m.heading_rad_per_sqrt_m):.2f} deg after 1 m",
            ),
            "heading_rad_per_sqrt_m",
        ),
    ]


def _calibration_table(log: str, c: Calibration, output: Path | None) -> str:
    m = c.model
    rows = _coefficient_rows(c)
    lines = [
        f"{log}: {c.windows} windows ({c.driving_windows} of {c.window_m:g} m, "
        f"{c.turning_windows} of {math.degrees(c.window_rad):g} deg turning), "
        f"{c.driven_m:.1f} m driven, {math.degrees(c.turned_rad):.0f} deg turned",
        "",
        f"{'':22s} {'odometry vs reference':24s} file",
    ]
    lines += [f"{a:22s} {b:24s} {key}: {_number(key, getattr(m, key))}" for a, b, key in rows]
    lines += [
        "systematic: the biases (build --correct-odometry takes them out; the file also holds",
        "their magnitudes, the spread of a bias left in); random: what error-aware maps spread",
    ]
    lines += _halves_lines(c, [key for _, _, key in rows])
    lines += _bias_lines(c)
    lines += ["", *_robust_lines(c)]
    if c.jitter_estimated:
        lines += [
            f"reference jitter (per pose, 1 sigma; not in the file): position "
            f"{100 * c.jitter_m:.1f} cm, heading {math.degrees(c.jitter_rad):.2f} deg. "
            "The reference is not truth:",
            "it was taken out of the random walks above (what stays the same at every window "
            "length is the reference's).",
        ]
    lines += _check_lines(c)
    lines += [
        "",
        f"residual per {c.window_m:g} m window (rms, systematic terms removed): distance "
        f"{100 * c.distance_residual_m:.2f} cm, heading "
        f"{math.degrees(c.heading_residual_rad):.3f} deg",
        f"wrote {output}" if output is not None else "(give -o FILE to write these)",
    ]
    return "\n".join(lines)


def _halves_lines(c: Calibration, keys: list[str]) -> list[str]:
    """The fit on each half of the span beside the whole's, where it was made."""
    if c.halves is None:
        return []
    lines = [
        "",
        "the same fit on each half of the span (by travel): do they transfer?",
        f"{'':30s} {'first half':>11s} {'second half':>11s} {'whole':>11s}",
    ]
    for key in keys:
        first, second = (getattr(h, key) for h in c.halves)
        values = (_number(key, v) for v in (first, second, getattr(c.model, key)))
        lines.append(f"{key:30s} " + " ".join(f"{v:>11s}" for v in values))
    return lines


#: How the calibrate table names each bias.
_BIAS_NAMES = {
    "distance_scale_bias": "distance scale",
    "turn_scale_bias": "turn scale",
    "heading_drift_bias_rad_per_m": "heading drift",
}


def _bias_lines(c: Calibration) -> list[str]:
    """Which biases were written: those the halves agree on and the whole tells from 0."""
    from gridmap_cli.poses.calibration.bias_check import NONE, SIGMA

    shown = [b for b in c.bias_checks if b.reason != NONE]
    if not shown:
        return []
    lines = [
        "",
        f"biases written when they stand {SIGMA:g} standard errors from 0 (the larger of the "
        "fit's and half the halves' difference):",
    ]
    for b in shown:
        verdict = "written" if b.applied else f"{b.reason}, not written"
        detail = f"whole {b.whole:+.4g} +- {b.se:.2g}"
        if b.halves is not None:
            detail += (
                f", halves {b.halves[0]:+.4g} / {b.halves[1]:+.4g}, "
                f"{b.disagreement:.1f} standard errors apart"
            )
        lines.append(f"{_BIAS_NAMES[b.key]}: {verdict} ({detail})")
    return lines


def _check_lines(c: Calibration) -> list[str]:
    """The check of the random walks on the positions, at a map's lengths."""
    if not math.isfinite(c.consistency):
        return []
    from gridmap_cli.poses.calibration.calibrate import WALK_KEYS

    cut = [n for n, w in zip(WALK_KEYS, c.walk_checked, strict=True) if w]
    return [
        f"check on the positions ({c.consistency_pairs} starts and horizons of 20 windows or "
        f"more): the odometry's error is {c.consistency:.2f} x what the random walks predict",
        f"cut by {c.random_walk_scale:.2f}, too weak in the windows to stand: {', '.join(cut)}"
        if cut
        else "random walks kept as the windows fitted them",
    ]


def _number(key: str, value: float) -> str:
    """A coefficient as the table shows it: the biases signed."""
    return (
        f"{value:+.4g}" if key.endswith(("_bias", "_bias_rad_per_m")) and value else f"{value:.4g}"
    )


def _robust_lines(c: Calibration) -> list[str]:
    """The windows the robust fit left out: how many of each length, and the worst few."""
    lengths = sorted({w.window_m for w in c.left_out})
    out = len(c.left_out)
    head = (
        f"robust fit: {c.fitted_windows} windows of {c.window_m:g} to "
        f"{c.window_m * max(JITTER_LADDER):g} m, {out} left out "
        f"({100 * out / max(c.fitted_windows, 1):.1f} %, beyond {OUTLIER_SIGMA:g} sigma of the "
        "rest: reference jumps, stamps off in fast turns)"
    )
    lines = [head]
    if out:
        counts = ", ".join(
            f"{sum(w.window_m == k for w in c.left_out)} of {k:g} m" for k in lengths
        )
        worst = sorted(c.left_out, key=lambda w: -abs(w.heading_error_rad))[:3]
        lines.append(
            f"left out: {counts}; the worst at "
            + ", ".join(
                f"{w.start_s:.1f} s ({math.degrees(w.heading_error_rad):+.1f} deg, "
                f"{100 * w.distance_error_m:+.0f} cm)"
                for w in worst
            )
            + " (all in --json: robust.left_out)"
        )
    return lines
