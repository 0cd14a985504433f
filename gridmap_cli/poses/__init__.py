"""Poses: from the log's tracks to a pose, and its uncertainty, for every reading.

Four jobs, one place each:

- pairing readings with poses: :mod:`.sync` gives each reading the robot pose at its stamp and
  the sensor's mounting;
- the odometry-error model: :mod:`.odometry_error` is the paper's f and g (eq. 10-12), and
  :mod:`.calibration` fits it against a reference track; :mod:`.track_error` measures a track
  against another (APE, RPE);
- pose uncertainty: :mod:`.uncertainty` carries the covariance along the odometry, or takes it
  from the pose graph's marginals;
- pose correction: :mod:`.correction` registers laser scans (scan matching) and closes loops on a
  pose graph (gtsam).

:mod:`.sources` names the pose sources a map is built with (odometry, the reference, the
corrections) in one table: the one place a source is chosen by name.

May import: the core and :mod:`gridmap_cli.robot`; nothing of mapping, readers or writers.
"""
