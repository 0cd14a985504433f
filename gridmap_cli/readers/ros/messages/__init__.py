"""Decoded ROS messages -> the canonical record stream, whatever container they came from.

The :class:`MessageAccumulator` takes the messages of the topics a
:class:`~gridmap_cli.readers.ros.topics.Plan` chose, in log-time order, as the MCAP, ROS 1 bag and
rosbag2 readers decode them (attribute access on ``mcap_ros1``/``mcap_ros2``/``rosbags`` objects,
dicts for gridmap's JSON channels), and :meth:`MessageAccumulator.finish` turns them into a
:class:`~gridmap_cli.records.RangeLog`:

- odometry: ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or ``gridmap.Pose2D``; without
  one, the odometry frame -> base transforms on ``/tf``. A pose topic named ``ground_truth`` is the
  reference track. Headings come from the quaternion (``2 atan2(qz, qw)`` for a planar one).
- sensor mounting: static transforms base -> sensor frame on ``/tf_static`` (``/tf`` in ROS 1
  recordings that have no static topic), chained through intermediate frames; else the robot
  description's sensor of the same name (``--robot``); else an error naming the frame.
- ranges: ``sensor_msgs/Range`` (one sensor per frame: field of view, min and max range),
  ``sensor_msgs/LaserScan`` (one ray sensor per beam, ``<frame>_<i>``),
  ``sensor_msgs/PointCloud`` as RosAria publishes sonar (one point per sonar, the echo's position
  in the robot frame; range = distance from the sonar's mount in ``--robot`` to the point), and
  ``gridmap.RangeReading`` with ``gridmap.RangeSensor`` descriptions.

Stamps are the messages' header stamps (``timestamp`` in JSON); a zero stamp falls back to the
message's log time. Frame ids are compared without a leading ``/``. ``docs/reading-ros.md``
states these rules for users.

The modules, one per message family, down the import order: :mod:`.fields` (stamps,
quaternions, float32 values), :mod:`.state` (what is held between messages), :mod:`.mounts`
(TF and sensor mountings), :mod:`.poses` (odometry and reference tracks), :mod:`.ranges`
(Range, LaserScan, sonar PointCloud, gridmap JSON readings) and :mod:`.accumulator`, which
combines them.

May import: the core, :mod:`gridmap_cli.robot` and, of this folder's siblings,
:mod:`~gridmap_cli.readers.ros.frames` and :mod:`~gridmap_cli.readers.ros.topics`; never the
readers that feed it (:mod:`gridmap_cli.readers.ros.mcap`, ``.bag``, ``.bulk``, ``.batches``).
"""

from gridmap_cli.readers.ros.messages.accumulator import MessageAccumulator
from gridmap_cli.readers.ros.messages.fields import float32_decimal

__all__ = ["MessageAccumulator", "float32_decimal"]
