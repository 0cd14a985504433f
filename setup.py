"""The one thing pyproject.toml cannot say: gridmap's compiled inner loops (issue 10).

Four small C extensions (plain CPython API and the buffer protocol, no numpy headers): the
mapping kernels of the sonar cone and the ray model; the record walks of the MCAP and bag
integrity checks; the closure search's branch and bound; the closure search's registrations.
All are optional: where no C compiler is at hand, the install still succeeds and the numpy /
Python reference paths do the work (gridmap_cli/mapping/models/kernels.py,
gridmap_cli/readers/ros/walk.py, gridmap_cli/poses/correction/correlative.py and
gridmap_cli/poses/correction/sheet_gicp.py choose; the last one's reference is small_gicp).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "gridmap_cli.mapping.models._ckernels",
            sources=["gridmap_cli/mapping/models/_ckernels.c"],
            # no fused multiply-adds: the kernels must round as the numpy reference does
            extra_compile_args=["-O2", "-ffp-contract=off"],
            optional=True,
        ),
        # the MCAP and ROS 1 bag integrity checks' per-record walks (gridmap_cli/readers/ros/walk.py)
        Extension(
            "gridmap_cli.readers.ros._cwalk",
            sources=["gridmap_cli/readers/ros/_cwalk.c"],
            extra_compile_args=["-O2"],
            optional=True,
        ),
        # the closure search's branch and bound (gridmap_cli/poses/correction/correlative.py)
        Extension(
            "gridmap_cli.poses.correction._cbranch",
            sources=["gridmap_cli/poses/correction/_cbranch.c"],
            # no fused multiply-adds: the scores must round as the numpy reference does
            extra_compile_args=["-O2", "-ffp-contract=off"],
            optional=True,
        ),
        # the closure search's registrations, small_gicp's sheet GICP in the plane
        # (gridmap_cli/poses/correction/sheet_gicp.py)
        Extension(
            "gridmap_cli.poses.correction._csheet",
            sources=["gridmap_cli/poses/correction/_csheet.c"],
            extra_compile_args=["-O2", "-ffp-contract=off"],
            optional=True,
        ),
    ]
)
