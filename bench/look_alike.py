"""Closure verification where places look alike: how many false closures ``verify`` accepts.

A simulated hall 10 m wide whose boxes repeat every PERIOD metres along it (rooms with the same
doors, shelves in a store); the robot drives down its middle lane and back along the same line,
a 3 m laser seeing boxes only. Each keyframe of the way back, every 1.3 m, is offered the
keyframe of the first pass ``off`` metres from the truth (0.3, 0.8, 1.5, 2.5 m either way), its
estimate put there (as a drifted estimate would offer it), with the candidate's search radius
given. A closure is *right* within 0.3 m of the truth; any other accepted closure is *false*.

Where the period is inside the search radius no verification can tell the copies apart; where
it is beyond it, the drift rule's radius kept them out until the coarse search placed the source
over the whole window (``max_search_m``) where GICP from the estimate fails. This prints how
many false closures each period and radius lets through, to judge a change to that search by.

    .venv/bin/python bench/look_alike.py                    # periods 3, 4, 6, 8 m; radius 2.5 m
    .venv/bin/python bench/look_alike.py --periods 6 --radius 1.5 3
"""

from __future__ import annotations

import argparse
import itertools
import math

import numpy as np
import numpy.typing as npt

from gridmap_cli.poses.correction.loop_closure import ClosureParams, Submaps, relative, verify

FloatArray = npt.NDArray[np.float64]

RANGE_M = 3.0
LENGTH_M = 40.0


def hall(rng: np.random.Generator, period_m: float, step_m: float = 0.05) -> FloatArray:
    """The outline points of three boxes, repeated every ``period_m`` along the hall."""
    unit = []
    for _ in range(3):
        x = rng.uniform(0.0, period_m - 1.5)
        y = rng.choice([rng.uniform(0.5, 4.0), rng.uniform(5.6, 9.0)])
        w, h = rng.uniform(0.4, 1.5, 2)
        unit.append((x, y, w, h))
    points = []
    for k in range(int(LENGTH_M / period_m)):
        for x0, y, w, h in unit:
            x = x0 + k * period_m
            corners = [(x, y), (x + w, y), (x + w, y + h), (x, y + h), (x, y)]
            for (ax, ay), (bx, by) in itertools.pairwise(corners):
                n = max(2, int(math.hypot(bx - ax, by - ay) / step_m))
                points.append(np.column_stack([np.linspace(ax, bx, n), np.linspace(ay, by, n)]))
    return np.vstack(points)


def scan(world: FloatArray, pose: FloatArray, rng: np.random.Generator) -> FloatArray:
    """The world's points within the laser's range, in the robot's frame, with 1 cm noise."""
    d = world - pose[:2]
    near = d[np.hypot(d[:, 0], d[:, 1]) <= RANGE_M]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    local = np.column_stack([c * near[:, 0] + s * near[:, 1], -s * near[:, 0] + c * near[:, 1]])
    return local + rng.normal(0.0, 0.01, local.shape)


def count(
    period_m: float,
    radius_m: float,
    offsets_m: tuple[float, ...] = (0.3, 0.8, 1.5, 2.5),
    seed: int = 5,
) -> tuple[int, int, int]:
    """Right, false and rejected closures over the offers described above, the estimate
    ``offsets_m`` from the truth."""
    rng = np.random.default_rng(seed)
    world = hall(rng, period_m)
    out = np.column_stack([np.arange(1.0, 39.0, 0.25), np.full(152, 5.0), np.zeros(152)])
    turn = np.column_stack([np.full(12, 39.0), np.full(12, 5.0), np.linspace(0, math.pi, 12)])
    back = np.column_stack([np.arange(39.0, 1.0, -0.25), np.full(152, 5.0), np.full(152, math.pi)])
    poses = np.vstack([out, turn, back])
    scans = [scan(world, p, rng) for p in poses]
    nodes = np.arange(0, len(poses), 2)
    truth = poses[nodes]
    submaps = Submaps(scans, poses, nodes, ClosureParams())

    def node_at(x: float, second: bool) -> int:
        half = np.flatnonzero(nodes >= 164 if second else nodes < 152)
        return int(half[np.argmin(np.abs(poses[nodes[half], 0] - x))])

    right = false = rejected = 0
    for x in np.arange(8.0, 32.0, 1.3):
        i = node_at(float(x), second=True)
        for off, sign in itertools.product(offsets_m, (1, -1)):
            j = node_at(float(x) + sign * off, second=False)
            tx, ty, tth = relative(truth, i, j)
            closure = verify(i, j, (tx + sign * off, ty + 0.2, tth + math.radians(1.5)),
                             submaps, radius_m)  # fmt: skip
            if closure is None:
                rejected += 1
                continue
            rx, ry, _ = relative(truth, closure.j, closure.i)
            if math.hypot(closure.dx_m - rx, closure.dy_m - ry) < 0.3:
                right += 1
            else:
                false += 1
    return right, false, rejected


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--periods", type=float, nargs="+", default=[3.0, 4.0, 6.0, 8.0])
    parser.add_argument("--radius", type=float, nargs="+", default=[2.5])
    args = parser.parse_args()
    print("| period | search radius | right | false | rejected |")
    print("|---|---|---|---|---|")
    for period, radius in itertools.product(args.periods, args.radius):
        right, false, rejected = count(period, radius)
        print(f"| {period:g} m | {radius:g} m | {right} | {false} | {rejected} |")


if __name__ == "__main__":
    main()
