"""The one thing pyproject.toml cannot say: gridmap's compiled mapping kernels (issue 10).

A small C extension (plain CPython API and the buffer protocol, no numpy headers) holds the
inner loops of the sonar cone, the error-aware cone and the ray model. It is optional: where no
C compiler is at hand, the install still succeeds and the numpy reference kernels do the work
(gridmap_cli/models/kernels.py chooses).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "gridmap_cli.models._ckernels",
            sources=["gridmap_cli/models/_ckernels.c"],
            # no fused multiply-adds: the kernels must round as the numpy reference does
            extra_compile_args=["-O2", "-ffp-contract=off"],
            optional=True,
        )
    ]
)
