"""Fitting the odometry-error model against a reference track (``gridmap calibrate``).

:mod:`.windows` cuts the log into windows of travel, :mod:`.robust_fit` fits the systematic
errors, random walks and jitter, :mod:`.calibrate` ties them together, and :mod:`.consistency`
checks the random walks at the lengths a map uses.
"""
