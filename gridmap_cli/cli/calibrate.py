"""``gridmap calibrate``: the odometry error model, from a log with a reference track."""

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
    handle_errors,
    json_text,
    read_input,
    selection_options,
)
from gridmap_cli.cli.progress import StageBars, reading
from gridmap_cli.errors import UsageError
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.readers import STDIN_NAME, format_names
from gridmap_cli.records import RangeLog
from gridmap_cli.writers import check_output

if TYPE_CHECKING:
    # scipy.ndimage (0.3 s) comes with it: imported when the command runs
    from gridmap_cli.poses.calibrate import Calibration


@click.command()
@click.argument("log", type=click.Path(path_type=Path, readable=False))
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path, readable=False),
    help="Odometry-error YAML to write (what build takes); default: print only.",
)
@click.option("--format", "log_format", type=click.Choice(format_names()), help="Log format.")
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
    type=click.Choice(("odometry", "scan-matched")),
    default="odometry",
    show_default=True,
    help="The track to calibrate against the reference: the odometry, or the odometry corrected "
    "by the laser (its residual drift, for error-aware maps built with --pose scan-matched).",
)
@click.option(
    "--robot",
    help="--pose scan-matched: robot preset, YAML or .p file with the laser's mounting; "
    "default: the log's own.",
)
@selection_options(sensors=False)
@click.option("--force", is_flag=True, help="Overwrite an existing output.")
@click.option("--json", "as_json", is_flag=True, help="Print the figures as JSON on stdout.")
@click.option("-q", "--quiet", is_flag=True, help="No table on stdout (with -o: just write).")
@handle_errors
def calibrate(
    log: Path,
    output: Path | None,
    log_format: str | None,
    window_m: float,
    window_deg: float,
    sonar_error: float,
    pose: str,
    robot: str | None,
    start: str | None,
    end: str | None,
    force: bool,
    as_json: bool,
    quiet: bool,
) -> None:
    """Estimate the odometry-error coefficients of LOG against its ground truth.

    LOG must carry ground truth (CSV true_x/true_y/true_theta, ARIA robotGlobal). Odometry and
    truth are compared over consecutive windows of travel; see docs/odometry-error.md.
    """
    from gridmap_cli.poses.calibrate import calibrate as calibrate_log
    from gridmap_cli.poses.odometry_error import save_odometry_error

    if not (window_m > 0.0 and math.isfinite(window_m)):
        raise UsageError(f"--window must be a positive number of metres, got {window_m}")
    if not (window_deg > 0.0 and math.isfinite(window_deg)):
        raise UsageError(f"--window-turn must be a positive number of degrees, got {window_deg}")
    if not (sonar_error >= 0.0 and math.isfinite(sonar_error)):
        raise UsageError(f"--sonar-error must be a finite number >= 0, got {sonar_error}")
    selection = Selection.parse((), start, end)
    check_input(log)
    if output is not None:
        check_output(output, force)
        check_output_folder(output)
    with reading(log.name, quiet):
        data = read_input([log], log_format)
    data = apply_selection(data, selection, None, need_readings=pose != "odometry").log
    if pose == "scan-matched":
        data = _scan_matched(log, data, robot, quiet)
    result = calibrate_log(data, window_m, math.radians(window_deg), sonar_error)
    if output is not None:
        save_odometry_error(
            result.model,
            output,
            comments=[
                f"gridmap {__version__} calibrate {log.name}"
                + (" --pose scan-matched" if pose != "odometry" else "")
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


def _scan_matched(path: Path, data: RangeLog, robot: str | None, quiet: bool) -> RangeLog:
    """The log with its odometry replaced by the scan-matched track (one pose per scan), the
    track whose residual drift against the reference is then calibrated."""
    from gridmap_cli.poses.scan_match import match_log
    from gridmap_cli.robot import load_robot, robot_from_log

    description = load_robot(robot) if robot else robot_from_log(path, data.metadata)
    with StageBars(quiet) as bars:
        track = match_log(data, description, progress=bars).track
    return dataclasses.replace(data, poses=track)


def _calibration_table(log: str, c: Calibration, output: Path | None) -> str:
    m = c.model

    def maybe(ok: bool, text: str) -> str:
        return text if ok else "not estimated"

    rows = [
        (
            "distance scale error",
            maybe(c.distance_estimated, f"{100 * c.scale_error:+.2f} % of distance"),
            f"range_m_per_m: {m.range_m_per_m:.4g}",
        ),
        (
            "distance random walk",
            maybe(c.distance_estimated, f"{100 * m.range_m_per_sqrt_m:.2f} cm after 1 m"),
            f"range_m_per_sqrt_m: {m.range_m_per_sqrt_m:.4g}",
        ),
        (
            "turn scale error",
            maybe(c.turn_estimated, f"{100 * c.turn_scale_error:+.2f} % of rotation"),
            f"bearing_rad_per_rad: {m.bearing_rad_per_rad:.4g}",
        ),
        (
            "turn random walk",
            maybe(
                c.turn_estimated,
                f"{math.degrees(m.bearing_rad_per_sqrt_rad):.2f} deg after 1 rad",
            ),
            f"bearing_rad_per_sqrt_rad: {m.bearing_rad_per_sqrt_rad:.4g}",
        ),
        (
            "heading drift",
            maybe(c.drift_estimated, f"{math.degrees(c.heading_drift_rad_per_m):+.3f} deg/m"),
            f"heading_drift_rad_per_m: {m.heading_drift_rad_per_m:.4g}",
        ),
    ]
    lines = [
        f"{log}: {c.windows} windows ({c.driving_windows} of {c.window_m:g} m, "
        f"{c.turning_windows} of {math.degrees(c.window_rad):g} deg turning), "
        f"{c.driven_m:.1f} m driven, {math.degrees(c.turned_rad):.0f} deg turned",
        "",
        f"{'':22s} {'odometry vs truth':24s} file",
    ]
    lines += [f"{a:22s} {b:24s} {f}" for a, b, f in rows]
    if c.halves is not None:
        keys = [f.split(":")[0] for _, _, f in rows]
        lines += [
            "",
            "the same fit on each half of the log (by distance driven): how far to trust it",
        ]
        for key in keys:
            first, second = (getattr(h, key) for h in c.halves)
            lines.append(
                f"{key:26s} {first:<10.4g} {second:<10.4g} (whole log {getattr(m, key):.4g})"
            )
    if c.jitter_estimated:
        lines += [
            "",
            f"reference jitter (per pose, 1 sigma; not in the file): position "
            f"{100 * c.jitter_m:.1f} cm, heading {math.degrees(c.jitter_rad):.2f} deg. "
            "The reference is not truth:",
            "it was taken out of the random walks above (what stays the same at every window "
            "length is the reference's).",
        ]
    lines += [
        "",
        f"residual per window (rms, systematic terms removed): distance "
        f"{100 * c.distance_residual_m:.2f} cm, heading "
        f"{math.degrees(c.heading_residual_rad):.3f} deg",
        f"wrote {output}" if output is not None else "(give -o FILE to write these)",
    ]
    return "\n".join(lines)
