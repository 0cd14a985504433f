"""How far each pose can be trusted.

:mod:`.pose_uncertainty` carries the covariance along the odometry from the error model;
:mod:`.pose_belief` takes it from a pose graph's marginals and draws whole tracks from it.
"""
