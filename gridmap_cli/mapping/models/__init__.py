"""Sensor models: turn readings with sensor poses into evidence on the grid.

The standard sonar cone (:mod:`.standard`, on the sector geometry of :mod:`.sector`), the ray
model of lasers (:mod:`.ray`) and the error-aware mode's analytic models, both of them with
their evidence faded by the pose spread (:mod:`.fading`, which holds the mode's settings too);
their inner loops are compiled (``_ckernels.c``) with a numpy reference that :mod:`.kernels`
falls back to.

May import: the core, :mod:`gridmap_cli.robot`, :mod:`gridmap_cli.poses` and the grid.
"""
