"""What a build is asked for and what it gives back: :class:`BuildOptions` (the map options,
checked by the CLI, as every mapping stage takes them) and :class:`BuildResult`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from gridmap_cli.mapping.grid import DEFAULT_CLAMP_P, DEFAULT_MAX_CELLS, OccupancyMap
from gridmap_cli.mapping.models.fading import ErrorAwareParams
from gridmap_cli.mapping.models.ray import RayParams
from gridmap_cli.mapping.models.standard import StandardSonarParams
from gridmap_cli.poses.odometry_error import OdometryError
from gridmap_cli.poses.sync import SyncStats
from gridmap_cli.poses.uncertainty.pose_belief import PoseBelief

if TYPE_CHECKING:  # the scan matcher and the fit load only for a build that checks
    from gridmap_cli.poses.calibration.log_check import FileCheck

MAPPING_MODES = ("standard", "error-aware")
#: The coarsest cell size build takes: a range sensor sees a few metres, so coarser cells map
#: nothing (``--resolution 1e6`` used to give a 2 x 2 map without a word).
MAX_RESOLUTION_M = 5.0


@dataclass(frozen=True)
class BuildOptions:
    """How to build a map. Units: metres; see docs/sensor-model.md for the model's defaults."""

    resolution_m: float = 0.05
    mode: str = "standard"
    sonar: StandardSonarParams = field(default_factory=StandardSonarParams)
    ray: RayParams = field(default_factory=RayParams)
    clamp_p: tuple[float, float] = DEFAULT_CLAMP_P
    error_aware: ErrorAwareParams = field(default_factory=ErrorAwareParams)
    odometry_error: OdometryError | None = None
    margin_m: float = 0.2
    max_cells: int = DEFAULT_MAX_CELLS
    batch_size: int = 20_000
    #: Error-aware mode: tracks sampled from the odometry-error model whose standard maps are
    #: averaged (the expected map, :func:`~gridmap_cli.mapping.pipeline.expected_map`); 0 maps
    #: with the analytic model, the standard models' evidence faded by the pose spread. 16 won
    #: on accuracy in every measurement (docs/sensor-model.md); its cost is in the README's Speed.
    error_samples: int = 16
    #: Seed of the sampled tracks: the same seed, the same map.
    error_seed: int = 0
    #: Take the signed systematic errors of ``odometry_error`` (version 3) out of the track
    #: before mapping, in either mode; the error-aware spread then has the random part alone
    #: (:func:`~gridmap_cli.mapping.pipeline.corrected_for_build`).
    correct_odometry: bool = False
    #: The odometry-error model was given (a file or coefficients), not the zero model a map of
    #: a pose graph's belief takes: a pose source that chooses by the log then maps the odometry.
    odometry_error_given: bool = False
    #: Error-aware mode: check ``odometry_error`` against the log's own laser before mapping
    #: (:func:`~gridmap_cli.poses.calibration.log_check.check_file`): a bias this log does not
    #: show is not corrected, random walks wider than its own error are narrowed.
    check_odometry_error: bool = False
    #: Processes mapping the readings; the map does not depend on it
    #: (:mod:`gridmap_cli.mapping.shards`).
    jobs: int = 1
    #: Error-aware mode: the pose graph's belief about the track (``--pose slam``), used instead
    #: of the odometry-error model: its marginals fade the readings, its draws are the sampled
    #: tracks. None: the covariance carried along the odometry by ``odometry_error``.
    pose_belief: PoseBelief | None = None


@dataclass(frozen=True)
class BuildResult:
    """The map and what went into it."""

    map: OccupancyMap
    sync: SyncStats
    cell_updates: int
    #: What the log's laser made of the odometry-error file (``check_odometry_error``).
    odometry_check: FileCheck | None = None

    @property
    def observed_cells(self) -> int:
        return self.map.cell_counts(1.0, 0.0)[0]
