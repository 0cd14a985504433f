"""MCAP files: reading a recording (:mod:`.log`) or streaming a long one (:mod:`.stream`),
its channels and schemas (:mod:`.channels`), bulk decoding of a chunk's channel (:mod:`.bulk`,
gridmap's own JSON messages in :mod:`.json_bulk`) and every CRC checked (:mod:`.integrity`).

May import: the core, :mod:`gridmap_cli.robot`, :mod:`gridmap_cli.readers.options` and the
shared ROS modules of :mod:`gridmap_cli.readers.ros`.
"""
