"""The work feed a placement lets the timing hold (camtool/placement/feed.py) and its term in the placement cost."""
import numpy as np
import pytest

from camtool.path.toolpath import ZONE_CODE, Path
from camtool.placement.feed import FeedStencils, expected_feed, row_feed, stencil_bounds, weighted_median
from camtool.placement.kinematics import ClosedForm
from camtool.placement.screen import PathGeometry, ScreenSettings, screen_batch
from camtool.robots import get_robot
from camtool.timing.pathlaw import PathSpline, speed_bounds
from camtool.timing.quintic import MARGIN
from camtool.timing.runs import time_runs

WORK = ZONE_CODE["work"]
FEED = 100.0
AWAY = (0.0, 400.0, 0.0, 0.0)    # the plate 400 mm to the side: q1 ~ 15 deg, the wrist bent as far


def _plate(centre, R, step=15.0, pitch=5.0, half_z=30.0, half_y=150.0):
    """A flat plate's zig-zag rows (along y, one row every ``step`` mm in z), the tool axis R[:, 2] throughout."""
    poses, seg, pt = [], [], []
    for k, z in enumerate(np.arange(-half_z, half_z + 1e-9, step)):
        ys = np.arange(-half_y, half_y + 1e-9, pitch)[::1 if k % 2 == 0 else -1]
        for j, y in enumerate(ys):
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, centre + [0.0, y, z]
            poses.append(T), seg.append(k), pt.append(j)
    return Path(np.array(poses), np.array(seg), np.array(pt), np.full(len(poses), WORK))


@pytest.fixture(scope="module")
def singular_plate():
    """The IRB2400 (no tool) and a strip of three rows 15 mm apart whose first two pass 7.5 mm either side of a
    wrist-singular pose: the closed form q = (0, a, -a, 0, 0, 0) puts joint 6's axis on joint 4's (q5 = 0)."""
    robot = get_robot("irb2400")
    q_sing = np.array([0.0, 0.2, -0.2, 0.0, 0.0, 0.0])
    S = robot.fk_tcp(q_sing)
    return robot, q_sing, S, _plate(S[:3, 3] + [0.0, 0.0, 7.5], S[:3, :3], half_z=15.0)


def test_the_plates_centre_is_wrist_singular(singular_plate):
    robot, q_sing, S, _ = singular_plate
    J = np.asarray(robot.jacobian(q_sing), float)        # Pinocchio's, not the screen's
    sv = np.linalg.svd(J, compute_uv=False)
    assert sv[-1] < 1e-9 * sv[0]
    assert np.allclose(S[:3, 2], [1.0, 0.0, 0.0])        # tool axis along the forearm, horizontal


def test_stencils_lie_on_one_row_of_work():
    zone, seg = [], []
    for s, n in enumerate((9, 3, 12)):                     # a row too short for a stencil in the middle
        zone += [ZONE_CODE["lead_in"]] + [WORK] * n + [ZONE_CODE["lead_out"]]
        seg += [s] * (n + 2)
    n = len(zone)
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    rng = np.random.default_rng(1)
    poses[:, :3, 3] = np.cumsum(rng.uniform(1.0, 3.0, (n, 3)), axis=0)
    path = Path(poses, np.array(seg), np.arange(n), np.array(zone))
    st = FeedStencils.build(path, 1000)
    seg, zone = np.array(seg), np.array(zone)
    assert len(st) == (9 - 3) + (12 - 3)                  # every centre i with i-1 .. i+2 work of one row
    assert (seg[st.index] == seg[st.index[:, :1]]).all() and (zone[st.index] == WORK).all()
    assert (np.diff(st.index, axis=1) == 1).all()
    p = poses[:, :3, 3]
    d = np.linalg.norm(p[st.index] - p[st.index[:, 1:2]], axis=-1)
    assert np.allclose(np.abs(st.s_mm[:, [0, 2]]), d[:, [0, 2]]) and (st.s_mm[:, 0] < 0).all()
    for r, s in enumerate(np.unique(seg)):                 # each row's work length: the direct sum of its steps
        w = np.flatnonzero((seg == s) & (zone == WORK))
        assert st.row_length_mm[r] == pytest.approx(np.linalg.norm(np.diff(p[w], axis=0), axis=1).sum())
    assert list(np.bincount(st.row, minlength=3)) == [6, 0, 9]
    assert len(FeedStencils.build(path, 5)) == 5


def test_stencil_bound_is_the_timing_bound_on_a_cubic(singular_plate):
    """On joints that are a cubic in s the bound is the timing's own (PathSpline's exact piece maxima)."""
    robot = singular_plate[0]
    rng = np.random.default_rng(3)
    for _ in range(5):
        s = np.cumsum(rng.uniform(2.0, 6.0, 4))
        c = rng.normal(0.0, [1.0, 0.02, 1e-3, 5e-5], (6, 4))  # per joint: c0 + c1 s + c2 s^2 + c3 s^3
        q = np.stack([np.polyval(ci[::-1], s) for ci in c], axis=1)   # (4, 6)
        spline = PathSpline(s, q)
        ref = speed_bounds(*(b[1:2] for b in spline.piece_bounds()), robot.limits, MARGIN)[0][0]
        mine = stencil_bounds(robot.limits, q[None], (s - s[1])[None])[0]
        assert mine == pytest.approx(ref, rel=1e-6)


def test_row_feed_is_the_rows_slowest_stencil_and_the_length_weighted_median():
    bound = np.array([120.0, 40.0, 90.0, 30.0, 100.0, 60.0])
    row = np.array([0, 0, 1, 1, 2, 3])
    length = np.array([100.0, 300.0, 50.0, 80.0, 999.0])     # row 4 has no stencil: not counted
    est = row_feed(bound, row, length, FEED)
    feeds = np.array([40.0, 30.0, 100.0, 60.0])             # by hand: each row's lowest, capped at the feed
    assert est.min_mm_s == 30.0 and est.median_mm_s == 30.0 and est.share == pytest.approx(0.3)   # 300 of 530 mm
    # the weighted median by its definition: the least value with half the weight at or below it
    order = np.sort(feeds)
    below = np.array([length[:4][feeds <= v].sum() for v in order])
    assert est.median_mm_s == order[np.argmax(below >= 0.5 * length[:4].sum())]
    assert weighted_median(np.array([1.0, 2.0, 3.0]), np.array([1.0, 1.0, 5.0])) == 3.0
    assert row_feed(np.zeros(0), np.zeros(0, int), length, FEED).share == 1.0


def _row_feeds(model, path, B):
    """The timing's own feed per row (``time_runs``, every pose, one continuous IK branch along the row)."""
    from camtool.placement.feed import _nearest

    T = np.einsum("ij,njk->nik", B, path.poses_mm)
    cands = model.candidates(T)
    q0, _, _ = model.best(T)
    q = q0.copy()
    for i in range(1, len(q)):
        if path.segment[i] == path.segment[i - 1]:
            q[i] = _nearest(cands[:, i:i + 1], q[i - 1:i], model.revolute)[0]
    step = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)
    first = np.r_[True, path.segment[1:] != path.segment[:-1]]
    last = np.r_[path.segment[1:] != path.segment[:-1], True]
    runs = time_runs(q, step, first, last, np.cumsum(first) - 1, path.zone, model.robot.limits, FEED)
    return runs.run_feed_mm_s


def test_the_feed_term_moves_the_plate_off_the_wrist_singularity(singular_plate):
    robot, _, S, path = singular_plate
    model = ClosedForm.for_robot(robot)
    here = (0.0, 0.0, 0.0, 0.0)
    # the timing itself: the rows that pass by the singularity crawl (j4 swings), 400 mm aside every row holds
    geom = PathGeometry.build(path, model, robot, S[:3, 3], ScreenSettings())
    slow = _row_feeds(model, path, geom.base_transform(here))
    held = _row_feeds(model, path, geom.base_transform(AWAY))
    assert np.median(slow) < 0.6 * FEED and slow.max() >= 0.99 * FEED and held.min() >= 0.99 * FEED
    # the screen, its own singularity margin (dexterity) set aside so that the feed term alone decides
    costs = {}
    for weight in (0.0, ScreenSettings().feed_weight):
        st = ScreenSettings(feed_weight=weight, dexterity_goal=1e-9, tcp_speed_mm_s=FEED)
        a, b = screen_batch(model, PathGeometry.build(path, model, robot, S[:3, 3], st), [here, AWAY], st)
        assert a.feasible and b.feasible
        costs[weight] = (a.cost, b.cost)
    assert costs[0.0][0] < costs[0.0][1]                  # without the term the part stays on the singularity
    assert costs[weight][1] < costs[weight][0]            # with it (the default weight), it moves aside
    assert b.feed_mm_s == pytest.approx(FEED)
    assert a.feed_mm_s == pytest.approx(np.median(slow), rel=0.15)  # the estimate against the time law's median
    est = expected_feed(model, geom.stencils, geom.poses_mm, geom.base_transform(here), FEED)
    assert est.median_mm_s == pytest.approx(a.feed_mm_s)
    # the finalists' check of every pose times every run by the time law itself
    a_full, b_full = screen_batch(model, geom, [here, AWAY], ScreenSettings(tcp_speed_mm_s=FEED), full=True)
    assert a_full.feed_mm_s == pytest.approx(np.median(slow), rel=1e-6) and b_full.feed_mm_s == pytest.approx(FEED)


def test_a_rows_sharpest_bend_gets_a_stencil():
    """Stencils go where the TCP pose bends most in each row (the joints' jerk peaks there), whatever the spread."""
    from scipy.spatial.transform import Rotation

    n = 200
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, 0, 3] = 5.0 * np.arange(n)
    bend = 137                                            # one pose tilted by 2 deg: the row's sharpest spot
    poses[bend, :3, :3] = Rotation.from_rotvec([0.0, np.radians(2.0), 0.0]).as_matrix()
    path = Path(poses, np.zeros(n, int), np.arange(n), np.full(n, WORK))
    st = FeedStencils.build(path, 8)
    assert len(st) <= 8
    assert (np.abs(st.index - bend) <= 2).any(axis=1).sum() >= 4     # the 4 stencils holding the bent pose
    straight = poses.copy()
    straight[bend, :3, :3] = np.eye(3)
    spread = FeedStencils.build(Path(straight, np.zeros(n, int), np.arange(n), np.full(n, WORK)), 8)
    assert not (np.abs(spread.index - bend) <= 2).any()  # unbent, they spread evenly and miss it
