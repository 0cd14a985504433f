"""A planar pose graph optimised with gtsam: nodes are keyframe poses, edges relative poses.

Edges carry a relative pose ``(dx, dy, dtheta)`` of node ``j`` in node ``i``'s frame and its
standard deviations (metres, metres, radians). Sequential edges (odometry and scan matching)
are Gaussian; loop closures go through a Cauchy kernel so that one wrong closure pulls the
graph with a bounded force instead of folding it. The graph is solved by Levenberg-Marquardt;
the marginal covariance of each pose comes from gtsam's ``Marginals``.

A *two-way* edge (:attr:`Edge.other`: a step whose scan match and odometry disagree far beyond
the log's usual) measures one of two ends, a max-mixture (Olson and Agarwal, 2012); which one,
the rest of the graph decides (:meth:`PoseGraph.optimise`).

Why gtsam: one wheel, Pose2 factors, robust noise models, LM and marginals in one library that
is well kept (Georgia Tech, BSD); the graphs here (hundreds to a few thousand nodes) solve in
well under a second.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import gtsam
import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import compose, inverse, logmap, relative_poses, wrap_angle

FloatArray = npt.NDArray[np.float64]
#: The Cauchy kernel's scale in each stage of :meth:`PoseGraph.optimise`, times ``cauchy_k``.
KERNEL_STAGES: tuple[float, ...] = (100.0, 10.0, 3.0, 1.0)
#: How much likelier (in chi-square units, twice the log-likelihood) the rest of the graph must
#: find a two-way edge's other end than the scan's before the edge takes it: the scan's end is
#: the default, as the matcher's own measurement, and a tie keeps it.
CHOICE_MARGIN = 1.0
#: Choices at most, each followed by a solve of the tightest stage, while a choice changes.
CHOICE_ROUNDS = 3


@dataclass(frozen=True)
class Edge:
    """Node ``j``'s pose in node ``i``'s frame, with standard deviations; ``closure`` marks a
    loop closure (robust kernel)."""

    i: int
    j: int
    dx_m: float
    dy_m: float
    dtheta_rad: float
    sigma_xy_m: float
    sigma_theta_rad: float
    closure: bool = False
    #: extra standard deviation (m) along ``weak_axis`` (unit vector, node j's frame): a stretch
    #: of featureless corridor, where the measurement is the odometry's (:mod:`.degeneracy`)
    weak_sigma_m: float = 0.0
    weak_axis: tuple[float, float] = (1.0, 0.0)
    #: a two-way edge's other end (x, y, node i's frame; the heading is the same): the
    #: odometry's where the scan match is doubted (:func:`.degeneracy.second_ends`), the scan's
    #: once the edge has taken the odometry's
    other: tuple[float, float] | None = None
    #: whether (``dx_m``, ``dy_m``) is the odometry's end, taken by :meth:`PoseGraph.optimise`
    taken: bool = False

    def swapped(self) -> Edge:
        """The two-way edge holding its other end."""
        assert self.other is not None
        return dataclasses.replace(
            self, dx_m=self.other[0], dy_m=self.other[1], other=(self.dx_m, self.dy_m),
            taken=not self.taken,
        )  # fmt: skip

    def spanning(self) -> tuple[tuple[float, float, float], FloatArray]:
        """A two-way edge as one Gaussian over both its ends: centred between them, with
        half the gap more standard deviation along it (node j's frame, as
        :meth:`covariance`)."""
        assert self.other is not None
        gap = np.array([self.other[0] - self.dx_m, self.other[1] - self.dy_m])
        c, s = np.cos(self.dtheta_rad), np.sin(self.dtheta_rad)
        along = np.array([c * gap[0] + s * gap[1], -s * gap[0] + c * gap[1]])
        cov = self.covariance()
        cov[:2, :2] += 0.25 * np.outer(along, along)
        mid = (self.dx_m + 0.5 * gap[0], self.dy_m + 0.5 * gap[1], self.dtheta_rad)
        return mid, cov

    def covariance(self) -> FloatArray:
        """The 3 x 3 covariance of (x, y, theta), node j's frame."""
        cov = np.diag([self.sigma_xy_m**2, self.sigma_xy_m**2, self.sigma_theta_rad**2])
        u = np.asarray(self.weak_axis)
        cov[:2, :2] += self.weak_sigma_m**2 * np.outer(u, u)
        return cov


@dataclass
class PoseGraph:
    """Nodes' initial poses (N, 3) x, y, theta and the edges between them."""

    initial: FloatArray
    edges: list[Edge] = field(default_factory=list)
    cauchy_k: float = 3.0
    _plain: dict[Edge, gtsam.BetweenFactorPose2] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )
    _noise: dict[Edge, gtsam.noiseModel.Base] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def _factors(
        self, cauchy_k: float | None = None, spanning: bool = False
    ) -> gtsam.NonlinearFactorGraph:
        """The factor graph, closures under a Cauchy kernel of ``cauchy_k`` (default: the
        graph's); ``spanning``: two-way edges as one Gaussian over both ends
        (:meth:`Edge.spanning`), else at the end each holds."""
        graph = gtsam.NonlinearFactorGraph()
        prior = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-3, 1e-3, 1e-4]))
        graph.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(*self.initial[0]), prior))
        kernel = gtsam.noiseModel.mEstimator.Cauchy.Create(cauchy_k or self.cauchy_k)
        for e in self.edges:
            if spanning and e.other is not None:
                mid, cov = e.spanning()
                loose = gtsam.noiseModel.Gaussian.Covariance(cov)
                graph.add(gtsam.BetweenFactorPose2(e.i, e.j, gtsam.Pose2(*mid), loose))
                continue
            if e.closure:
                noise = gtsam.noiseModel.Robust.Create(kernel, self._gaussian(e))
                rel = gtsam.Pose2(e.dx_m, e.dy_m, e.dtheta_rad)
                graph.add(gtsam.BetweenFactorPose2(e.i, e.j, rel, noise))
                continue
            # a Gaussian edge's factor does not depend on the kernel: made once, shared by
            # every graph built from this one (the closure search rebuilds it per stage)
            factor = self._plain.get(e)
            if factor is None:
                rel = gtsam.Pose2(e.dx_m, e.dy_m, e.dtheta_rad)
                factor = gtsam.BetweenFactorPose2(e.i, e.j, rel, self._gaussian(e))
                self._plain[e] = factor
            graph.add(factor)
        return graph

    def _gaussian(self, e: Edge) -> gtsam.noiseModel.Base:
        noise = self._noise.get(e)
        if noise is None:
            noise = (
                gtsam.noiseModel.Gaussian.Covariance(e.covariance())
                if e.weak_sigma_m > 0
                else gtsam.noiseModel.Diagonal.Sigmas(
                    np.array([e.sigma_xy_m, e.sigma_xy_m, e.sigma_theta_rad])
                )
            )
            self._noise[e] = noise
        return noise

    def optimise(
        self,
        start: FloatArray | None = None,
        scales: tuple[float, ...] = KERNEL_STAGES,
        choose: bool = True,
    ) -> FloatArray:
        """The optimised poses (N, 3), from ``start`` (default: the initial poses).

        The kernel is tightened in stages (``cauchy_k``, 3 whitened sigmas, times each of
        ``scales``, by default :data:`KERNEL_STAGES`): a closure far from a drifted start
        would get almost no weight from a tight kernel and never pull; a wide one first lets
        the true closures (which agree with each other) win, and the tight one last takes the
        weight off those the rest of the graph disagrees with.

        Two-way edges: with ``choose``, the stages hold each as one Gaussian over both its ends
        (:meth:`Edge.spanning`), so the closures can put a correction at either; then each
        edge takes the end the rest of that solution finds likelier (:meth:`_choose`), all at
        once, and the tightest stage is solved again with the ends chosen; then the choice is
        made again at that solution, and so on while one changes, at most
        :data:`CHOICE_ROUNDS` times. The choice at the spanning solution alone is not enough:
        there every other doubted step is loose too, and it takes odometry ends that the
        solution with the ends held gives back. Two neighbouring edges, each the other's
        rest, can swing back and forth; the last choice is kept. A plain max-mixture started
        at the scan's ends never leaves them: a closure's pull spreads along the chain and
        brings no single step near its other end.
        Without ``choose`` every edge keeps the end it holds (a cheaper solve, where the
        result only guides the search for more closures).
        """
        seed = self.initial if start is None else start
        values = _values(seed)
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(100)
        params.setRelativeErrorTol(1e-6)
        spanning = choose and any(e.other is not None for e in self.edges)
        for scale in scales:
            factors = self._factors(self.cauchy_k * scale, spanning)
            values = gtsam.LevenbergMarquardtOptimizer(factors, values, params).optimize()
        for _ in range(CHOICE_ROUNDS if spanning else 0):
            changed = self._choose(values, self.cauchy_k * scales[-1], spanning)
            factors = self._factors(self.cauchy_k * scales[-1])
            values = gtsam.LevenbergMarquardtOptimizer(factors, values, params).optimize()
            spanning = False
            if not changed:
                break
        return _poses(values, len(seed))

    def _choose(self, values: gtsam.Values, cauchy_k: float, spanning: bool) -> bool:
        """Each two-way edge set to hold the end that the rest of the graph, solved at
        ``values`` (two-way edges ``spanning`` both their ends, or at the ends they hold),
        finds likelier; whether any changed.

        The rest's belief about the edge's relative pose is the solution's with the edge's own
        factor taken out again: on the linearised graph, information ``P^-1 - C_f^-1`` (``P``
        the solution's covariance of the relative pose, ``C_f`` the factor's) and information
        vector ``-C_f^-1 z_f`` (``z_f`` the factor's measurement, in the tangent at the
        solution, where the posterior's mean is 0). An end ``a`` is as likely as the rest's
        Gaussian widened by the edge's own noise ``C`` says: ``(a - mu)^T (L^-1 + C)^-1 (a - mu)``
        with ``L`` that information, taken as ``(I + L C)^-1 L`` so that a rest that knows
        nothing (no closure across the step: ``L = 0``) finds both ends alike and the scan's
        is kept."""
        two = [k for k, e in enumerate(self.edges) if e.other is not None]
        edges = [self.edges[k] for k in two]
        poses = _poses(values, values.size())
        net = self._factors(cauchy_k, spanning).linearize(values).eliminateSequential()
        est, predicted = _predicted(poses, edges, _edge_covariances(net, edges, len(poses)))
        changed = False
        for k, e, x, p in zip(two, edges, est, predicted, strict=True):
            assert e.other is not None
            held, other = (e.dx_m, e.dy_m, e.dtheta_rad), (*e.other, e.dtheta_rad)
            scan, odo = (other, held) if e.taken else (held, other)
            z_f, c_f = e.spanning() if spanning else (held, e.covariance())
            own = np.linalg.inv(c_f)
            rest = np.linalg.inv(p) - own
            # the rest's information: positive semi-definite, but for rounding where it is ~0
            eigen, vectors = np.linalg.eigh(0.5 * (rest + rest.T))
            rest = (vectors * np.clip(eigen, 0.0, None)) @ vectors.T
            eta = -own @ _tangent(x, z_f)
            widen = np.linalg.inv(np.eye(3) + rest @ e.covariance())
            m, m_mu = widen @ rest, widen @ eta
            m = 0.5 * (m + m.T)
            a_s, a_o = _tangent(x, scan), _tangent(x, odo)
            d_s = float(a_s @ m @ a_s - 2.0 * a_s @ m_mu)
            d_o = float(a_o @ m @ a_o - 2.0 * a_o @ m_mu)
            if (d_o + CHOICE_MARGIN < d_s) != e.taken:
                self.edges[k] = e.swapped()
                changed = True
        return changed

    def marginals(self, poses: FloatArray) -> FloatArray:
        """Each node's marginal covariance at ``poses``, shape (N, 3, 3), in the node's own
        frame (x, y, theta; metres and radians), as gtsam gives it."""
        values = _values(poses)
        marginals = gtsam.Marginals(self._factors(), values)
        return np.stack([marginals.marginalCovariance(k) for k in range(len(poses))])

    def residual_budget(self, poses: FloatArray) -> FloatArray:
        """The a posteriori variance budget of the graph at ``poses`` (its optimum): shape (2, 2),
        rows translation (x and y pooled) and rotation, columns the edges' summed whitened
        squared residual and their redundancy (the share of each edge's information the rest of
        the graph does not already fix: ``1 - sigma^-2 var(predicted)``, summed; the ratio of
        the two is the variance factor, 1 when the edge noise is right).

        A loop closure counts with its robust kernel's weight at the residual, as the optimiser
        weighs it. Without a loop the redundancy is 0: nothing checks the noise."""
        if not self.edges:
            return np.zeros((2, 2))
        est, predicted = _predicted(poses, self.edges, self.edge_covariances(poses))
        # each edge's error against the measured relative pose, in the tangent space as the
        # optimiser sees it
        measured = np.array([(e.dx_m, e.dy_m, e.dtheta_rad) for e in self.edges])
        r = np.column_stack(logmap(*compose(*inverse(*measured.T), *est.T)))
        # the edge's own information, looser along a corridor (:meth:`Edge.covariance`), as
        # the optimiser weighs it; x, y and theta do not mix in it
        info = np.linalg.inv(np.stack([e.covariance() for e in self.edges]))
        weight = np.ones(len(self.edges))
        closure = np.array([e.closure for e in self.edges])
        # Cauchy: w = 1 / (1 + |r|^2 / k^2) on the whitened residual
        whitened = np.einsum("ei,eij,ej->e", r, info, r)
        weight[closure] = 1.0 / (1.0 + whitened[closure] / self.cauchy_k**2)
        t_info, t_r = info[:, :2, :2], r[:, :2]
        out = np.zeros((2, 2))
        out[0] = (
            float(np.sum(weight * np.einsum("ei,eij,ej->e", t_r, t_info, t_r))),
            float(np.sum(2.0 - weight * np.einsum("eij,eji->e", t_info, predicted[:, :2, :2]))),
        )
        out[1] = (
            float(np.sum(weight * info[:, 2, 2] * r[:, 2] ** 2)),
            float(np.sum(1.0 - weight * info[:, 2, 2] * predicted[:, 2, 2])),
        )
        return out

    def edge_covariances(self, poses: FloatArray) -> FloatArray:
        """The joint covariance of each edge's two nodes at ``poses`` (the optimum), shape
        (E, 6, 6): node i's block first, each in the node's own frame as gtsam's joint
        marginals give it (:func:`_edge_covariances`)."""
        net = self._factors().linearize(_values(poses)).eliminateSequential()
        return _edge_covariances(net, self.edges, len(poses))

    def sample(self, poses: FloatArray, count: int, seed: int = 0) -> FloatArray:
        """``count`` joint draws of every node's pose from the graph's Gaussian at ``poses``
        (the optimum): shape (count, N, 3).

        The graph is linearised there and eliminated into its square-root information R (upper
        triangular, R^T R the information); ``R d = z`` with ``z`` standard normal gives a
        tangent step ``d`` whose covariance is the inverse information, so the draws keep the
        correlations along the path (neighbours move together, as the edges between them say)
        and each node's spread is its marginal's. (gtsam's own ``GaussianBayesNet.sample``
        adds the conditionals' unit sigmas after solving, not ``R^-1 z``: not this.)
        """
        values = _values(poses)
        net = self._factors().linearize(values).eliminateSequential()
        mean = net.optimize()  # about 0 at the optimum; kept so the draws centre on the belief
        rng = np.random.default_rng(seed)
        out = np.empty((count, len(poses), 3))
        for s in range(count):
            z = gtsam.VectorValues()
            for k in range(len(poses)):
                z.insert(k, rng.standard_normal(3))
            spread = net.backSubstitute(z)
            step = gtsam.VectorValues()
            for k in range(len(poses)):
                step.insert(k, spread.at(k) + mean.at(k))
            out[s] = _poses(values.retract(step), len(poses))
        return out

    def covariance_product(self, poses: FloatArray, vectors: FloatArray) -> FloatArray:
        """``Sigma v`` for each ``v`` of ``vectors`` (M, N, 3), ``Sigma`` the joint covariance
        of every node at ``poses`` (each node's block in its own frame, as :meth:`marginals`):
        shape (M, N, 3). Two triangular solves per vector with the square-root information, so
        the joint covariance (3N x 3N) is never formed."""
        values = _values(poses)
        net = self._factors().linearize(values).eliminateSequential()
        out = np.empty(vectors.shape)
        for m, vector in enumerate(vectors):
            rhs = gtsam.VectorValues()
            for k in range(len(poses)):
                rhs.insert(k, np.ascontiguousarray(vector[k], dtype=np.float64))
            product = net.backSubstitute(net.backSubstituteTranspose(rhs))
            out[m] = [product.at(k) for k in range(len(poses))]
        return out


def _predicted(
    poses: FloatArray, edges: list[Edge], joint: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Each edge's relative pose at ``poses`` (node j in node i's frame), shape (E, 3), and its
    covariance there (E, 3, 3), from ``joint``, the edges' two nodes' joint covariances
    (:func:`_edge_covariances`)."""
    i = np.array([e.i for e in edges])
    j = np.array([e.j for e in edges])
    est = relative_poses(poses[i], poses[j])
    # the relative pose's Jacobian in the two nodes: [-Adjoint(est^-1), I]
    ix, iy, ith = inverse(*est.T)
    c, s = np.cos(ith), np.sin(ith)
    jac = np.zeros((len(edges), 3, 6))
    jac[:, 0, 0], jac[:, 0, 1], jac[:, 0, 2] = -c, s, -iy
    jac[:, 1, 0], jac[:, 1, 1], jac[:, 1, 2] = -s, -c, ix
    jac[:, 2, 2] = -1.0
    jac[:, :, 3:] = np.eye(3)
    return est, jac @ joint @ np.transpose(jac, (0, 2, 1))


def _tangent(at: FloatArray, pose: tuple[float, float, float]) -> FloatArray:
    """``pose`` (a relative pose) in the tangent space at ``at``: log(at^-1 pose)."""
    x, y, th = compose(*inverse(*at), *pose)
    return np.array([float(v) for v in logmap(x, y, th)])


def _values(poses: FloatArray) -> gtsam.Values:
    values = gtsam.Values()
    for k, (x, y, th) in enumerate(poses):
        values.insert(k, gtsam.Pose2(float(x), float(y), float(th)))
    return values


def _edge_covariances(net: gtsam.GaussianBayesNet, edges: list[Edge], n: int) -> FloatArray:
    """The joint covariance of each edge's two nodes, shape (E, 6, 6) (node i's block first,
    each in its own frame as gtsam's joint marginals give it), from ``net``, the square-root
    information of the ``n`` nodes eliminated one at a time.

    The inverse is taken only where it is needed, on the pattern of the square root (Takahashi's
    selected inverse, block by block): with the conditional of node k ``R x_k + S x_P = d``
    over its parents P, eliminated after it, ``Sigma_kP = -R^-1 S Sigma_PP`` and
    ``Sigma_kk = R^-1 R^-T - R^-1 S Sigma_Pk``, taken in reverse elimination order. The parents
    of a conditional are each other's parents or children, so ``Sigma_PP`` is known by then,
    and the two nodes of an edge are one the other's parent. Exact: the same covariances as a
    joint marginal per edge, at a few per cent of the cost, since each is a product of small
    blocks already computed rather than a new factorisation."""
    conditionals = [net.at(c) for c in range(net.size())]
    keys = [list(map(int, c.keys())) for c in conditionals]
    blocks = np.empty((sum(2 * len(k) - 1 for k in keys), 3, 3))
    at: dict[int, int] = {}  # row * n + column -> the covariance block's index in blocks
    used = 0
    for conditional, (node, *parents) in zip(reversed(conditionals), reversed(keys), strict=True):
        r_inv = np.linalg.inv(conditional.R())
        m = len(parents)
        own = r_inv @ r_inv.T
        if m:
            rows = [at[p * n + q] for p in parents for q in parents]
            among = blocks[rows].reshape(m, m, 3, 3).transpose(0, 2, 1, 3).reshape(3 * m, 3 * m)
            gain = r_inv @ conditional.S()
            cross = -gain @ among  # Sigma_kP, (3, 3m)
            own = own - gain @ cross.T
            blocks[used : used + m] = cross.reshape(3, m, 3).transpose(1, 0, 2)
            blocks[used + m : used + 2 * m] = blocks[used : used + m].transpose(0, 2, 1)
            for a, p in enumerate(parents):
                at[node * n + p] = used + a
                at[p * n + node] = used + m + a
            used += 2 * m
        blocks[used] = own
        at[node * n + node] = used
        used += 1
    pairs = [[at[u * n + v] for u in (e.i, e.j) for v in (e.i, e.j)] for e in edges]
    four = blocks[np.array(pairs, dtype=np.int64).reshape(-1, 4)].reshape(-1, 2, 2, 3, 3)
    out: FloatArray = four.transpose(0, 1, 3, 2, 4).reshape(-1, 6, 6)
    return out


def _poses(values: gtsam.Values, n: int) -> FloatArray:
    out = np.empty((n, 3))
    for k in range(n):
        p = values.atPose2(k)
        out[k] = p.x(), p.y(), p.theta()
    return out


def edge_residuals(poses: FloatArray, edges: list[Edge]) -> FloatArray:
    """Each edge's error at ``poses``: (E, 2) translation (m) and |rotation| (rad) of the
    measured relative pose against the estimated one."""
    if not edges:
        return np.zeros((0, 2))
    dx, dy, dth = edge_errors(poses, edges).T
    return np.column_stack([np.hypot(dx, dy), np.abs(dth)])


def edge_errors(poses: FloatArray, edges: list[Edge]) -> FloatArray:
    """Each edge's error at ``poses`` as a pose (E, 3): the estimated relative pose seen from
    the measured one (x, y in node j's frame, metres; theta wrapped, radians)."""
    if not edges:
        return np.zeros((0, 3))
    i = np.array([e.i for e in edges])
    j = np.array([e.j for e in edges])
    ix, iy, ith = inverse(poses[i, 0], poses[i, 1], poses[i, 2])
    ex, ey, eth = compose(ix, iy, ith, poses[j, 0], poses[j, 1], poses[j, 2])
    mx, my, mth = inverse(
        np.array([e.dx_m for e in edges]),
        np.array([e.dy_m for e in edges]),
        np.array([e.dtheta_rad for e in edges]),
    )
    dx, dy, dth = compose(mx, my, mth, ex, ey, eth)
    return np.column_stack([dx, dy, wrap_angle(dth)])


def largest_bend(poses: FloatArray, edges: list[Edge]) -> float:
    """The largest error of ``edges`` at ``poses`` in their own standard deviations: the
    translation whitened by the edge's x, y covariance (looser along a corridor), the rotation
    by its sigma."""
    if not edges:
        return 0.0
    errors = edge_errors(poses, edges)
    worst = 0.0
    for e, (dx, dy, dth) in zip(edges, errors, strict=True):
        shift = np.array([dx, dy])
        cov = e.covariance()[:2, :2]
        worst = max(
            worst,
            math.sqrt(float(shift @ np.linalg.solve(cov, shift))),
            abs(float(dth)) / e.sigma_theta_rad,
        )
    return worst
