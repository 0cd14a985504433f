"""ROS recordings, read without a ROS installation: MCAP files (:mod:`.mcap`), ROS 1 bags and
rosbag2 folders (:mod:`.bag`), and what they share: the message decoders (:mod:`.messages`),
decoding whole channels at once (:mod:`.bulk`, :mod:`.batches`), topics found by type
(:mod:`.topics`), quaternions and TF chains (:mod:`.frames`), the record walks of the
integrity checks (:mod:`.walk`, compiled in ``_cwalk.c``) and the merge of several sources into
one recording (:mod:`.recording`).

May import: the core, :mod:`gridmap_cli.robot` and :mod:`gridmap_cli.readers.options`; never
the registry in :mod:`gridmap_cli.readers` (it imports this package lazily).
"""
