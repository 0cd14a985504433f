"""Better poses from the laser: scan matching and loop closure on a pose graph.

:mod:`.scan_match` registers each scan against a local map (small_gicp), keeping the odometry
along a corridor's weak axis (:mod:`.degeneracy`); :mod:`.slam` adds loop closures
(:mod:`.loop_closure`, verified by a correlative search, :mod:`.correlative`) on a pose graph
(:mod:`.pose_graph`, gtsam); :mod:`.carry` spreads a correction known at some poses to every pose.
"""
