"""Issue 20's library choice, measured: the pose graph ``--pose slam`` builds on the Intel lab,
optimised by gtsam (gridmap's) and by g2o (``g2opy``, when installed; not a dependency) with the
same factors and the same staged Cauchy kernel, from the same start.

Prints each library's optimisation time (in-process, the graph built in Python each time) and
how far g2o's optimum lies from gtsam's.

    .venv/bin/python bench/pose_graph_libraries.py
    (pip install g2opy into the venv first for the comparison; without it only gtsam is timed)
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.correction.pose_graph import PoseGraph
from gridmap_cli.poses.correction.slam import slam_corrected_log
from gridmap_cli.readers import read_log

INTEL = Path(__file__).resolve().parents[2] / "shared/data/carmen/intel-corrected.log.gz"
#: Kernel widths, in units of the graph's Cauchy k, as PoseGraph.optimise stages them.
STAGES = (100.0, 10.0, 3.0, 1.0)


def g2o_optimise(graph: PoseGraph) -> npt.NDArray[np.float64] | None:
    """The graph optimised by g2o's Levenberg-Marquardt, staged like gtsam's; None without g2o."""
    try:
        import g2opy as g
    except ImportError:
        return None
    opt = g.SparseOptimizer()
    opt.set_algorithm(g.OptimizationAlgorithmLevenberg(g.BlockSolverSE2(g.LinearSolverEigenSE2())))
    for n, (x, y, th) in enumerate(graph.initial):
        v = g.VertexSE2()
        v.set_id(n)
        v.set_estimate(g.SE2(float(x), float(y), float(th)))
        v.set_fixed(n == 0)  # gtsam's tight prior on the first node
        opt.add_vertex(v)
    kernels = []
    for e in graph.edges:
        edge = g.EdgeSE2()
        edge.set_vertex(0, opt.vertex(e.i))
        edge.set_vertex(1, opt.vertex(e.j))
        edge.set_measurement(g.SE2(e.dx_m, e.dy_m, e.dtheta_rad))
        edge.set_information(np.diag([e.sigma_xy_m**-2, e.sigma_xy_m**-2, e.sigma_theta_rad**-2]))
        if e.closure:
            kernel = g.RobustKernelCauchy(graph.cauchy_k)
            edge.set_robust_kernel(kernel)
            kernels.append(kernel)
        opt.add_edge(edge)
    opt.initialize_optimization()
    for scale in STAGES:
        for kernel in kernels:
            kernel.set_delta(graph.cauchy_k * scale)
        opt.optimize(100)
    return np.array([opt.vertex(n).estimate().vector() for n in range(len(graph.initial))])


def main() -> None:
    if not INTEL.is_file():
        print(f"{INTEL} is not here: nothing to measure")
        return
    _, result = slam_corrected_log(read_log(INTEL), None)
    graph = result.graph
    assert graph is not None
    closures = sum(e.closure for e in graph.edges)
    print(f"Intel lab pose graph: {len(graph.initial)} nodes, {len(graph.edges)} edges "
          f"({closures} loop closures)")  # fmt: skip
    started = time.perf_counter()
    ours = graph.optimise()
    print(f"  gtsam (gridmap's)  {time.perf_counter() - started:6.3f} s")
    started = time.perf_counter()
    theirs = g2o_optimise(graph)
    if theirs is None:
        print("  g2o                skipped (g2opy is not installed here)")
        return
    elapsed = time.perf_counter() - started
    moved = float(np.hypot(*(theirs[:, :2] - ours[:, :2]).T).max())
    turned = float(np.abs(wrap_angle(theirs[:, 2] - ours[:, 2])).max())
    print(f"  g2o                {elapsed:6.3f} s   its optimum: at most {moved:.4f} m and "
          f"{np.degrees(turned):.4f} deg from gtsam's")  # fmt: skip


if __name__ == "__main__":
    main()
