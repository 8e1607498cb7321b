"""The vectorised pieces of the fast System 2 against hand-worked values and per-hull references."""

import math

import numpy as np
import pytest

from dualpilot.evaluation.instances import SPEC, make_instance
from dualpilot.model.dynamics import DynamicsParams, reach_boxes
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.plan import PlanStatus
from dualpilot.system2.fast.geometry import (
    FaceStack,
    HullStack,
    Inflated,
    support_toward,
)
from dualpilot.system2.fast.ipm import Rows, band_pairs, solve_qp
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.fast.references import all_candidates
from dualpilot.system2.problem import System2Params, disjunction_margin

DYN = DynamicsParams()
SQUARE = Rect(500.0, 500.0, 200.0, 200.0).polytope()  # [400, 600]²; Q at ε = 25: [375, 625]²
TRIANGLE = Polytope.from_vertices(np.array([[100.0, 100.0], [200.0, 100.0], [150.0, 180.0]]))


def test_hull_stack_support_by_hand():
    """Face region: the face itself; vertex region: the line through the corner, normal ∝ p − c."""
    q = Inflated.make(SQUARE, 25.0)
    stack = HullStack.of([Inflated.make(TRIANGLE, 25.0), q])  # padded: 3 and 4 faces
    pts = np.array([[700.0, 500.0], [700.0, 700.0], [500.0, 500.0]])
    nrm, off, outside = stack.support(np.array([1, 1, 1]), pts)
    np.testing.assert_allclose(nrm[0], [1.0, 0.0])
    assert off[0] == pytest.approx(625.0)
    np.testing.assert_allclose(nrm[1], [math.sqrt(0.5), math.sqrt(0.5)])
    assert off[1] == pytest.approx(625.0 * math.sqrt(2.0))
    assert outside.tolist() == [True, True, False]
    # the centre is 125 m inside Q: the margin is −125 m
    np.testing.assert_allclose(stack.margin(np.array([1, 1, 1]), pts), [75.0, 75.0, -125.0])
    c, d = stack.nearest(np.array([1]), pts[1:2])
    np.testing.assert_allclose(c[0], [625.0, 625.0])
    assert d[0] == pytest.approx(75.0 * math.sqrt(2.0))


def test_hull_stack_matches_each_inflated_hull():
    inst = make_instance(3, 5, 20)
    polys = Inflated.make_many(inst.hulls, 25.0)
    stack = HullStack.of(polys)
    rng = np.random.default_rng(0)
    for i in range(0, len(polys), 3):
        q = polys[i]
        c = q.W.mean(axis=0)
        pts = c + rng.normal(scale=80.0, size=(40, 2))
        want = c + rng.normal(scale=80.0, size=(40, 2))
        hid = np.full(40, i)
        for got, ref in ((stack.support(hid, pts), q.support(pts)),
                         (stack.support_toward(hid, pts, want, slack=0.01),
                          support_toward(q, pts, want, slack=0.01))):
            np.testing.assert_allclose(got[0], ref[0], atol=1e-9)
            np.testing.assert_allclose(got[1], ref[1], rtol=1e-12, atol=1e-9)
            assert np.array_equal(got[2], ref[2])
        np.testing.assert_allclose(stack.margin(hid, pts), q.margin(pts), atol=1e-9)


def test_make_many_matches_inflate_per_hull():
    """Concatenated inflation of hulls with 3 and 4 faces equals each hull's own."""
    many = Inflated.make_many([TRIANGLE, SQUARE, TRIANGLE], 25.0)
    for q, hull in zip(many, [TRIANGLE, SQUARE, TRIANGLE], strict=True):
        np.testing.assert_allclose(q.W, Inflated.make(hull, 25.0).W)
        np.testing.assert_allclose(q.E, np.roll(q.W, -1, axis=0) - q.W)
        np.testing.assert_allclose(q.b, hull.b + 25.0)
    np.testing.assert_allclose(many[1].W, [[375.0, 375.0], [625.0, 375.0], [625.0, 625.0],
                                           [375.0, 625.0]])
    np.testing.assert_allclose(many[1].lo, [375.0, 375.0])
    np.testing.assert_allclose(many[1].hi, [625.0, 625.0])


def test_disjunction_margin_by_hand():
    """Square [0, 10]², ε = 1: (15, 5) is 5 − 1 = 4 m out, (12, 12) is 2 − 1 = 1 m out."""
    hull = Rect(5.0, 5.0, 10.0, 10.0).polytope()
    far = Rect(505.0, 505.0, 10.0, 10.0).polytope()
    assert disjunction_margin(np.array([[15.0, 5.0]]), [hull, far], 1.0) == pytest.approx(4.0)
    pts = np.array([[15.0, 5.0], [12.0, 12.0]])
    assert disjunction_margin(pts, [far, hull], 1.0) == pytest.approx(1.0)
    assert disjunction_margin(pts, [], 1.0) == math.inf
    faces = FaceStack.of([hull, far])
    np.testing.assert_allclose(faces.margins(pts)[:, 0], [5.0, 2.0])


def test_face_stack_margins_and_below_match_each_hull():
    """The compiled margins equal each inflated hull's own (max over its faces), and
    ``below`` is margin < threshold where the mask allows, nothing elsewhere."""
    polys = Inflated.make_many(make_instance(3, 5, 20).hulls, 25.0)
    faces = FaceStack.of(polys)
    pts = np.random.default_rng(1).uniform(0.0, 1000.0, size=(60, 2))
    margins = faces.margins(pts)
    for i, q in enumerate(polys):
        np.testing.assert_allclose(margins[:, i], q.margin(pts), rtol=0, atol=1e-9)
    mask = np.random.default_rng(2).random((len(polys), len(pts))) < 0.5
    for threshold in (0.0, 60.0):
        np.testing.assert_array_equal(faces.below(pts, threshold, mask),
                                      mask & (threshold > margins.T))
        np.testing.assert_array_equal(faces.below(pts, threshold), threshold > margins.T)
    # by hand: Q = [375, 625]² (ε = 25); (700, 500) is 75 m out, the centre 125 m in
    sq = FaceStack.of([Inflated.make(SQUARE, 25.0)])
    centre_and_out = np.array([[500.0, 500.0], [700.0, 500.0]])
    np.testing.assert_allclose(sq.margins(centre_and_out)[:, 0], [-125.0, 75.0])
    assert sq.below(centre_and_out, 75.0).tolist() == [[True, False]]
    assert FaceStack.of([]).margins(centre_and_out).shape == (2, 0)


def test_banded_ipm_box_qp_by_hand():
    """min ½‖z‖² − q·z s.t. z ≥ lo has the solution z = max(q, lo)."""
    n = 12
    q_lin = np.linspace(-1.0, 1.0, n)
    lo = np.full(n, 0.25)
    j = np.arange(n)
    rows = Rows.make(np.column_stack([j, j, j]), np.column_stack([np.ones(n), np.zeros(n),
                                                                   np.zeros(n)]),
                     lo, np.full(n, np.inf))
    h_band = np.zeros((7, n))
    h_band[0] = 1.0
    res = solve_qp(h_band, -q_lin, rows, band_pairs(rows, n))
    assert res.ok
    np.testing.assert_allclose(res.z, np.maximum(q_lin, lo), atol=1e-5)


def _timing_reference(planner, path, speeds, v0, factor=1.0):
    """The numpy-scalar loop that References.timing replaced."""
    rho = planner.fast.speed_factor * factor
    dyn = planner.dynamics
    d = np.diff(path, axis=0)
    seg = np.linalg.norm(d, axis=1)
    good = seg > 1e-9
    d, seg = d[good], seg[good]
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    axis_factor = seg / np.maximum(np.max(np.abs(d), axis=1), 1e-9)
    v_cap = rho * dyn.v_max_mps * axis_factor
    a_cap = rho * dyn.u_max_n / dyn.mass_kg * axis_factor
    sigma = max(0.0, float(v0 @ d[0]) / seg[0])
    s = np.zeros(len(speeds) + 1)
    for k, v in enumerate(speeds):
        j = min(max(int(np.searchsorted(cum, s[k], side="right")) - 1, 0), len(seg) - 1)
        sigma = min(v_cap[j], (1.0 - dyn.zeta) * sigma + a_cap[j] * dyn.dt_s,
                    factor * max(float(v), 0.0))
        s[k + 1] = min(cum[-1], s[k] + dyn.dt_s * sigma)
    return s


def test_timing_is_the_same_recursion():
    planner = FastSystem2(SPEC, System2Params())
    path = np.array([[50.0, 50.0], [300.0, 60.0], [300.0, 60.0], [500.0, 400.0], [950.0, 950.0]])
    rng = np.random.default_rng(2)
    speeds = rng.uniform(-1.0, 20.0, size=80)
    for v0, factor in ((np.array([5.0, 0.0]), 1.0), (np.array([-3.0, 2.0]), 0.35)):
        got = planner.references.timing(path, speeds, v0, factor)
        assert np.array_equal(got, _timing_reference(planner, path, speeds, v0, factor))
    # a path that is finished: the arc length stops at its length
    short = np.array([[0.0, 0.0], [30.0, 40.0]])
    arc = planner.references.timing(short, np.full(80, 15.0), np.zeros(2))
    assert arc[-1] == pytest.approx(50.0)


def _candidates_reference(q, g):
    """The per-hull candidates that references.all_candidates replaced: G_o projected onto
    every edge of Q and Q's vertices, each pushed 2 m outwards."""
    a = q.W
    e = np.roll(a, -1, axis=0) - a
    len2 = np.maximum(np.einsum("ij,ij->i", e, e), 1e-12)
    t = np.clip(((g - a) * e).sum(axis=1) / len2, 0.0, 1.0)
    proj = a + t[:, None] * e
    bis = np.roll(q.A, 1, axis=0) + q.A
    corners = a + 2.0 * bis / np.maximum(np.linalg.norm(bis, axis=1), 1e-9)[:, None]
    return np.vstack([proj + 2.0 * q.A, corners])


def test_all_candidates_are_each_hulls_candidates():
    polys = Inflated.make_many([TRIANGLE, SQUARE, TRIANGLE], 25.0)
    g = np.array([950.0, 950.0])
    pts, owner = all_candidates(polys, g)
    want = np.vstack([_candidates_reference(q, g) for q in polys])
    np.testing.assert_allclose(pts, want, rtol=0, atol=1e-12)
    assert owner.tolist() == [0] * 6 + [1] * 8 + [2] * 6


def test_covered_goal_target_is_two_metres_outside():
    """G_o = (900, 900) inside Q = [825, 975]×[865, 985] (hull [850, 950]×[890, 960], ε = 25):
    the nearest face is y = 865 (35 m), pushed 2 m out: (900, 863); a far hull changes nothing."""
    params = System2Params()
    planner = FastSystem2(SPEC, params)
    cover = Rect(900.0, 925.0, 100.0, 70.0).polytope()
    far = Rect(100.0, 100.0, 50.0, 50.0).polytope()
    polys = Inflated.make_many([far, cover], SPEC.clearance_m)
    np.testing.assert_allclose(planner.references.target(polys), [900.0, 863.0], atol=1e-9)


def test_start_checks_name_the_right_hull_among_far_ones():
    """p_t = (95, 100) is 25 m from hull 2 (x ≥ 120), p_{t+1} = p_t + 1 s·(15, 0) = (110, 100)
    only 10 m (< ε = 25): INFEASIBLE, naming hull 2 behind two far hulls."""
    planner = FastSystem2(SPEC, System2Params())
    far = [Rect(800.0, 100.0 + 100.0 * k, 20.0, 20.0).polytope() for k in range(2)]
    near = Rect(140.0, 100.0, 40.0, 80.0).polytope()  # [120, 160]×[60, 140]
    state = np.array([95.0, 100.0, 15.0 / DYN.dt_s, 0.0])
    plan = planner.plan(state, far + [near], prev_control=np.zeros(2))
    assert plan.status is PlanStatus.INFEASIBLE
    assert "hull 2" in plan.message
    # 5 m further back, p_t is 20 m from it and p_{t+1} 15 m: still hull 2, still infeasible
    state[0] = 90.0
    plan = planner.plan(state, far + [near], prev_control=np.zeros(2))
    assert plan.status is PlanStatus.INFEASIBLE and "hull 2" in plan.message


def _reach_boxes_reference(x0, horizon, dyn):
    """The numpy loop that dualpilot.dynamics.reach_boxes replaced."""
    keep = 1.0 - dyn.zeta
    acc = dyn.dt_s / dyn.mass_kg * dyn.u_max_n
    v_hi = x0[2:].copy()
    v_lo = x0[2:].copy()
    p_hi = x0[:2] + dyn.dt_s * v_hi
    p_lo = p_hi.copy()
    lo, hi = [p_lo.copy()], [p_hi.copy()]
    for _ in range(horizon - 1):
        v_hi = np.minimum(keep * v_hi + acc, dyn.v_max_mps)
        v_lo = np.maximum(keep * v_lo - acc, -dyn.v_max_mps)
        p_hi = p_hi + dyn.dt_s * v_hi
        p_lo = p_lo + dyn.dt_s * v_lo
        lo.append(p_lo.copy())
        hi.append(p_hi.copy())
    return np.array(lo), np.array(hi)


def test_plain_float_reach_boxes_equal_the_numpy_ones():
    rng = np.random.default_rng(4)
    for _ in range(20):
        x0 = np.concatenate([rng.uniform(0.0, 1000.0, 2), rng.uniform(-15.0, 15.0, 2)])
        lo, hi = reach_boxes(x0, 80, DYN)
        want_lo, want_hi = _reach_boxes_reference(x0, 80, DYN)
        assert np.array_equal(lo, want_lo) and np.array_equal(hi, want_hi)
    # at rest, one step: p_{t+1} = p_t on both sides
    lo, hi = reach_boxes(np.array([10.0, 20.0, 0.0, 0.0]), 1, DYN)
    np.testing.assert_allclose(lo, [[10.0, 20.0]])
    np.testing.assert_allclose(hi, [[10.0, 20.0]])


def test_rebound_solves_the_same_qp_as_a_fresh_context():
    """A cached structure with new bounds and linear term gives a fresh context's solution."""
    n = 12
    j = np.arange(n)
    cols = np.column_stack([j, j, j])
    vals = np.column_stack([np.ones(n), np.zeros(n), np.zeros(n)])
    h_band = np.zeros((7, n))
    h_band[0] = 2.0
    from dualpilot.system2.fast.ipm import BandedQp

    rows1 = Rows.make(cols, vals, np.full(n, 0.25), np.full(n, np.inf))
    base = BandedQp(h_band, np.zeros(n), rows1, band_pairs(rows1, n))
    q2 = -2.0 * np.linspace(-1.0, 1.0, n)  # unconstrained optimum z = linspace(-1, 1)
    lo2 = np.full(n, -0.5)
    rows2 = Rows.make(cols, vals, lo2, np.full(n, np.inf))
    fresh = BandedQp(h_band, q2, rows2, band_pairs(rows2, n)).solve()
    again = base.rebound(q2, lo2, np.full(n, np.inf)).solve()
    assert fresh.ok and again.ok
    np.testing.assert_allclose(again.z, np.maximum(np.linspace(-1.0, 1.0, n), -0.5), atol=1e-5)
    assert np.array_equal(again.z, fresh.z)
    with pytest.raises(ValueError):
        base.rebound(q2, np.full(n, -np.inf), np.full(n, np.inf))


def test_csr_matvec_adds_in_scipys_order():
    """The compiled A x equals scipy's A @ x bit for bit (rows of 1 to 9 terms, any order)."""
    import scipy.sparse as sp

    from dualpilot.system2.fast.mehrotra import csr_matvec

    rng = np.random.default_rng(3)
    for k in range(50):
        a = sp.random(40, 30, density=0.1 + 0.2 * (k % 3), random_state=k, format="csr")
        a.data *= 10.0 ** rng.uniform(-3, 3, a.nnz)
        x = rng.normal(size=30) * 10.0 ** rng.uniform(-3, 3, 30)
        assert np.array_equal(csr_matvec(a.indptr, a.indices, a.data, x), a @ x)


def test_p2qp_of_one_shape_share_their_matrices_not_their_state():
    """A second P2Qp of the same shape reuses the first one's matrices and memo tables,
    keeps its own backend and per-plan state, and solves the same QP to the same bits."""
    from dualpilot.system2.fast.qp import P2Qp, QpParams

    a = P2Qp(20, DYN, 1000.0)
    b = P2Qp(20, DYN, 1000.0, QpParams(backend="clarabel"))
    c = P2Qp(20, DynamicsParams(speed_limit="norm"), 1000.0)
    assert a.shape is b.shape and a.shape.U is b.shape.U
    assert c.shape is not a.shape and c.shape.norm and not a.shape.norm
    assert a.backend == "ipm" and b.backend == "clarabel"
    x0, u0 = np.array([100.0, 120.0, 3.0, -2.0]), np.array([0.5, -0.25])
    goal, kappa = np.array([900.0, 850.0]), (1.0, 0.1)
    none = (np.zeros(0, int), np.zeros((0, 2)), np.zeros(0))
    first = a.solve(x0, u0, goal, kappa, *none, confirm=True)
    fresh = P2Qp(20, DYN, 1000.0)
    assert fresh._ctx is None  # nothing of a's plan
    second = fresh.solve(x0, u0, goal, kappa, *none, confirm=True)
    assert first.ok and np.array_equal(first.positions, second.positions)
    assert first.objective == second.objective


@pytest.mark.parametrize("backend", ["ipm", "clarabel"])
@pytest.mark.parametrize("tau", [1, 0, 21])
def test_p2qp_refuses_a_half_plane_outside_p2_to_pT(backend: str, tau: int):
    """Half-planes constrain p_2..p_T (p_1 is fixed by x_0): τ outside is a ValueError on
    either backend, never an out-of-bounds read in the compiled solver."""
    from dualpilot.system2.fast.qp import P2Qp, QpParams

    qp = P2Qp(20, DYN, 1000.0, QpParams(backend=backend))
    x0, u0 = np.array([100.0, 120.0, 3.0, -2.0]), np.array([0.5, -0.25])
    with pytest.raises(ValueError, match="half-planes apply to p_2..p_20"):
        qp.solve(x0, u0, np.array([900.0, 850.0]), (1.0, 0.1), np.array([tau]),
                 np.array([[1.0, 0.0]]), np.array([50.0]))


def test_planners_of_one_shape_plan_alike_from_two_threads(monkeypatch: pytest.MonkeyPatch):
    """A fleet's planners share the QP structures from their own threads: with a cache of
    two (evictions all the time) each thread's plans equal those planned alone."""
    import threading

    import dualpilot.system2.fast.qp as qp_module

    monkeypatch.setattr(qp_module, "STRUCTURES_KEPT", 2)
    instances = [make_instance(i, 11, 1 + i % 4) for i in range(8)]

    def plan_all() -> list[np.ndarray]:
        planner = FastSystem2(SPEC)
        return [planner.plan(inst.state, inst.hulls, inst.objective, inst.prev_control).states
                for inst in instances for _ in range(2)]

    alone = plan_all()
    results: dict[int, list[np.ndarray]] = {}
    threads = [threading.Thread(target=lambda k=k: results.__setitem__(k, plan_all()))
               for k in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for k in range(2):
        assert len(results[k]) == len(alone)
        assert all(np.array_equal(a, b) for a, b in zip(results[k], alone, strict=True))
