"""camtool.design core: Pareto dominance, the archive, repulsion, narrowing and the
two-step MOPSO on analytic problems (no planner, no pymoo)."""
import numpy as np
import pytest

from camtool.design import (MopsoSettings, ParetoArchive, dominates, narrow_ranges, nondominated_mask,
                            parse_vary, repulsion_velocity, run_mopso)
from camtool.design.mopso import mutate, mutation_probability
from camtool.design.pareto import crowding_distance, grid_cells
from camtool.errors import BadInput


# -- dominance ----------------------------------------------------------------------------

def test_dominates_known_pairs():
    assert dominates([1, 1], [2, 2])
    assert dominates([1, 2], [1, 3])          # equal in one, better in the other
    assert not dominates([1, 2], [1, 2])      # equal vectors do not dominate
    assert not dominates([1, 3], [2, 2])      # a trade-off
    assert not dominates([2, 2], [1, 1])
    assert dominates([0, 0, 0], [0, 0, 1])


def test_nondominated_mask_on_a_known_front():
    F = np.array([[1, 5], [2, 3], [3, 4], [4, 1], [2, 3], [5, 5], [1.5, 4]])
    # (3,4) is dominated by (2,3); (5,5) by everything; the duplicate (2,3) stays
    assert nondominated_mask(F).tolist() == [True, True, False, True, True, False, True]


def test_nondominated_mask_matches_brute_force():
    rng = np.random.default_rng(3)
    F = rng.integers(0, 6, (40, 2)).astype(float)
    mask = nondominated_mask(F)
    for i in range(len(F)):
        assert mask[i] == (not any(dominates(F[j], F[i]) for j in range(len(F)) if j != i))


def test_crowding_distance_boundaries_infinite():
    d = crowding_distance(np.array([[0.0, 4], [1, 2], [2, 1], [4, 0]]))
    assert np.isinf(d[0]) and np.isinf(d[3])
    assert d[1] == pytest.approx(2 / 4 + 3 / 4) and d[2] == pytest.approx(3 / 4 + 2 / 4)


# -- archive ----------------------------------------------------------------------------

def test_archive_keeps_only_nondominated():
    a = ParetoArchive(capacity=10, rng=np.random.default_rng(0))
    assert a.add([0.0], [3, 3])
    assert a.add([1.0], [1, 4])
    assert not a.add([2.0], [4, 4])           # dominated by (3,3)
    assert a.add([3.0], [2, 2])               # dominates (3,3): that one leaves
    X, F = a.sorted()
    assert F.tolist() == [[1, 4], [2, 2]]
    assert X.ravel().tolist() == [1.0, 3.0]
    assert not a.add([3.0], [2, 2])           # the same design again
    assert a.add([4.0], [2, 2])               # another design of equal merit is kept


def test_archive_capacity_drops_from_crowded_cubes():
    a = ParetoArchive(capacity=5, divisions=4, rng=np.random.default_rng(1))
    # a sparse end point and a dense cluster on a line front
    pts = [[0.0, 10.0]] + [[9.0 + 0.01 * k, 1.0 - 0.01 * k] for k in range(10)]
    for k, f in enumerate(pts):
        a.add([float(k)], f)
    assert len(a) == 5
    assert [0.0, 10.0] in a.F.tolist()        # the lone point in its cube is never dropped


def test_leader_roulette_prefers_sparse_cubes():
    a = ParetoArchive(capacity=50, divisions=5, rng=np.random.default_rng(2))
    a.add([0.0], [0.0, 10.0])
    for k in range(9):
        a.add([1.0 + k], [10.0 - 0.001 * k, 0.001 * k])
    picks = [a.leader()[0] for _ in range(2000)]
    share = np.mean(np.array(picks) == 0.0)
    # cube fitness 10/1 vs 10/9: the lone member leads 90 % of the time
    assert 0.85 < share < 0.95


def test_grid_cells_separate_far_points():
    cells = grid_cells(np.array([[0.0, 0.0], [0.01, 0.0], [1.0, 1.0]]), 10)
    assert cells[0] == cells[1] != cells[2]


# -- repulsion, narrowing, mutation ------------------------------------------------------

def test_repulsion_moves_a_particle_away_from_an_invalid_point():
    obstacle = np.array([[0.5, 0.5]])
    u = np.array([[0.55, 0.52]])
    v = repulsion_velocity(u, obstacle, gain=0.002, radius=0.15, cap=0.25)
    assert np.linalg.norm(v) > 0
    before = np.linalg.norm(u - obstacle)
    after = np.linalg.norm(u + v - obstacle)
    assert after > before
    # the push is along the line from the obstacle to the particle
    direction = (u - obstacle) / before
    assert np.allclose(v / np.linalg.norm(v), direction)


def test_repulsion_falls_off_and_ignores_far_obstacles():
    obstacle = np.array([[0.0, 0.0]])
    near = np.linalg.norm(repulsion_velocity([[0.05, 0.0]], obstacle, 0.002, 0.15, 10.0))
    mid = np.linalg.norm(repulsion_velocity([[0.10, 0.0]], obstacle, 0.002, 0.15, 10.0))
    far = np.linalg.norm(repulsion_velocity([[0.20, 0.0]], obstacle, 0.002, 0.15, 10.0))
    assert near > mid > far == 0.0
    capped = repulsion_velocity([[0.01, 0.0]], obstacle, 0.002, 0.15, 0.25)
    assert np.linalg.norm(capped) == pytest.approx(0.25)
    # a particle on an obstacle gets no push from it (it is that obstacle)
    assert np.all(repulsion_velocity([[0.0, 0.0]], obstacle, 0.002, 0.15, 0.25) == 0)


def test_repulsion_from_two_sides_cancels():
    v = repulsion_velocity([[0.5, 0.5]], [[0.45, 0.5], [0.55, 0.5]], 0.002, 0.15, 10.0)
    assert np.allclose(v, 0.0)


def test_narrow_ranges_cuts_invalid_ends():
    rng = np.random.default_rng(0)
    X = rng.uniform([300, 300], [600, 500], (400, 2))
    valid = (X[:, 0] > 450) & (X[:, 1] > 380)      # invalid below L1 450 or L3 380
    lo, hi = narrow_ranges(X, valid, [300, 300], [600, 500])
    assert 420 <= lo[0] <= 450 and hi[0] == 600
    assert 360 <= lo[1] <= 380 and hi[1] == 500
    # an archive member outside the box widens it again
    lo2, _ = narrow_ranges(X, valid, [300, 300], [600, 500], keep_X=np.array([[400.0, 450.0]]))
    assert lo2[0] == 400.0
    # no valid design: nothing to narrow to
    lo3, hi3 = narrow_ranges(X, np.zeros(len(X), bool), [300, 300], [600, 500])
    assert lo3.tolist() == [300, 300] and hi3.tolist() == [600, 500]


def test_mutation_probability_decays_and_stays_in_bounds():
    assert mutation_probability(0, 10, 0.5) == 1.0
    assert mutation_probability(5, 10, 0.5) == pytest.approx(0.25)
    assert mutation_probability(10, 10, 0.5) == 0.0
    X = np.full((50, 2), 0.5)
    Y = mutate(X, np.zeros(2), np.ones(2), 1.0, np.random.default_rng(0))
    assert np.all((Y >= 0) & (Y <= 1))
    assert np.all(np.sum(Y != X, axis=1) <= 1) and np.any(Y != X)


# -- MOPSO on analytic problems ------------------------------------------------------------

def schaffer_with_hole(X):
    """Two objectives (x1+x2, (x1-1)^2 + (x2-1)^2); designs with x1 + x2 < 0.6 are invalid."""
    X = np.atleast_2d(X)
    F = np.column_stack([X[:, 0] + X[:, 1], (X[:, 0] - 1) ** 2 + (X[:, 1] - 1) ** 2])
    return F, np.where(X.sum(axis=1) < 0.6, 1.0, 0.0)


def test_mopso_is_deterministic_with_a_seed():
    s = MopsoSettings(particles=8, explore_iters=2, optimise_iters=3)
    a = run_mopso(schaffer_with_hole, [0, 0], [1, 1], s, np.random.default_rng(5), resolution=0.01)
    b = run_mopso(schaffer_with_hole, [0, 0], [1, 1], s, np.random.default_rng(5), resolution=0.01)
    c = run_mopso(schaffer_with_hole, [0, 0], [1, 1], s, np.random.default_rng(6), resolution=0.01)
    assert np.array_equal(a.X, b.X) and np.array_equal(a.front_F, b.front_F)
    assert not np.array_equal(a.X, c.X)
    assert a.evaluations == s.budget == 48


def test_mopso_front_is_valid_nondominated_and_on_grid():
    s = MopsoSettings(particles=10, explore_iters=3, optimise_iters=6)
    r = run_mopso(schaffer_with_hole, [0, 0], [1, 1], s, np.random.default_rng(0), resolution=0.01)
    assert len(r.front_F) >= 3
    assert nondominated_mask(r.front_F).all()
    F, v = schaffer_with_hole(r.front_X)
    assert np.all(v == 0) and np.allclose(F, r.front_F)
    assert np.allclose(r.front_X, np.round(r.front_X / 0.01) * 0.01)
    # nothing any evaluation found dominates the front
    ok = r.violation == 0
    for f in r.F[ok]:
        assert not any(dominates(f, g) for g in r.front_F)
    # the invalid set is exactly the invalid evaluations
    assert np.all(r.invalid_X.sum(axis=1) < 0.6)
    assert np.all(r.X[r.step == 2] >= r.narrowed_lower - 1e-9)
    assert np.all(r.X[r.step == 2] <= r.narrowed_upper + 1e-9)


def test_mopso_narrows_away_an_invalid_corner():
    def corner(X):
        X = np.atleast_2d(X)
        F = np.column_stack([X[:, 0] + X[:, 1], -X[:, 0] * X[:, 1]])
        return F, np.where((X[:, 0] < 0.4) | (X[:, 1] < 0.3), 1.0, 0.0)

    s = MopsoSettings(particles=20, explore_iters=3, optimise_iters=2)
    r = run_mopso(corner, [0, 0], [1, 1], s, np.random.default_rng(1))
    assert r.narrowed_lower[0] >= 0.2 and r.narrowed_lower[1] >= 0.1
    step2 = r.step == 2
    step1 = r.step == 1
    # fewer invalid evaluations once the ranges are narrowed
    assert np.mean(r.violation[step2] > 0) < np.mean(r.violation[step1] > 0)


def test_repulsion_reduces_invalid_evaluations():
    """With the potential field on, the swarm meets fewer invalid designs (same seeds)."""
    def blob(X):
        X = np.atleast_2d(X)
        F = np.column_stack([X[:, 0], X[:, 1]])
        return F, np.where(np.linalg.norm(X - [0.3, 0.3], axis=1) < 0.25, 1.0, 0.0)

    on = off = 0
    for seed in range(6):
        for gain, acc in ((0.002, "on"), (0.0, "off")):
            s = MopsoSettings(particles=12, explore_iters=4, optimise_iters=0, repulsion_gain=gain,
                              mutation_rate=0.1)
            r = run_mopso(blob, [0, 0], [1, 1], s, np.random.default_rng(seed))
            n = int(np.sum(r.violation[r.iteration > 0] > 0))
            if acc == "on":
                on += n
            else:
                off += n
    assert on < off


def test_mopso_rejects_bad_settings():
    with pytest.raises(ValueError):
        MopsoSettings(particles=1)
    with pytest.raises(ValueError):
        run_mopso(schaffer_with_hole, [0, 1], [1, 1], MopsoSettings(particles=4, explore_iters=0,
                                                                    optimise_iters=0))


# -- --vary parsing ----------------------------------------------------------------------

def test_parse_vary_good_and_bad():
    v = parse_vary("L1=300:600")
    assert (v.name, v.lower_mm, v.upper_mm) == ("L1", 300.0, 600.0)
    for bad in ("L1", "L1=300", "L1=a:600", "L1=600:300", "L1=500:500", "L1=-5:10", "L1=nan:5"):
        with pytest.raises(BadInput) as e:
            parse_vary(bad)
        assert "\n" not in str(e.value)
