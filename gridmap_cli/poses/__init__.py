"""Poses: from the log's tracks to a pose, and its uncertainty, for every reading.

:mod:`.sync` gives each reading the robot pose at its stamp and the sensor's mounting;
:mod:`.odometry_error` is the paper's model of the odometry's accumulated error (f and g, eq.
10-12); :mod:`.calibrate` fits it against a reference track; :mod:`.track_error` measures a
track against another (APE, RPE); :mod:`.scan_match` corrects odometry by registering laser
scans; :mod:`.slam` adds loop closures (:mod:`.loop_closure`) on a pose graph (:mod:`.pose_graph`,
gtsam).

May import: the core and :mod:`gridmap_cli.robot`; nothing of mapping, readers or writers.
"""
