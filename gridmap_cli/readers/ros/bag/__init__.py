"""ROS 1 bags and rosbag2 folders (sqlite3 or MCAP storage), through ``rosbags``: reading a
recording (:mod:`.log`), bulk decoding of a connection (:mod:`.bulk`) and the bag's record
structure checked before it is read (:mod:`.integrity`).

May import: the core, :mod:`gridmap_cli.robot`, :mod:`gridmap_cli.readers.options`, the shared
ROS modules of :mod:`gridmap_cli.readers.ros` and :mod:`gridmap_cli.readers.ros.mcap` (a rosbag2
folder may store MCAP).
"""
