"""Leads lifted clear of the part (camtool.path.lead_clearance), against a part whose signed distance is closed form:
the plane z = 0 rising at 45 deg beyond x = 103 mm, just past the first row's work end (a recess's rim, a flange)."""
import numpy as np

from camtool.path.lead_clearance import LEAD_CLEAR_MM, cleared_leads
from camtool.path.toolpath import ZONE_CODE, Path

RISE_X_MM = 103.0


def signed_distance(P):
    """mm in front of the part z <= max(0, x - 103) (+), inside it (-): exact for the slope's side and the plane."""
    P = np.atleast_2d(P)
    x, z = P[:, 0], P[:, 2]
    # above the plane and above the slope: the distance to the nearer of the two (inside: minus the depth)
    return np.minimum(z, (z - (x - RISE_X_MM)) / np.sqrt(2.0))


def two_row_path():
    """Two rows along x at y = 0 and y = 25 (the second back), each with two lead poses of 15 mm either side
    (unlifted), three self-motion poses between them, approach and depart; tool z pointing down (-z)."""
    rows = []
    zone, seg = [], []
    for s, (y, way) in enumerate(((0.0, 1.0), (25.0, -1.0))):
        xs = np.arange(0.0, 100.01, 10.0)[::int(way)]
        lead_in = xs[0] - way * np.array([15.0, 7.5])
        lead_out = xs[-1] + way * np.array([7.5, 15.0])
        if s == 1:
            mid = np.array([[x, 12.5, 5.0] for x in (110.0, 112.0, 110.0)])
            rows.append(mid)
            zone += ["self_motion"] * 3
            seg += [1] * 3
        for xx, z in ((lead_in, "lead_in"), (xs, "work"), (lead_out, "lead_out")):
            rows.append(np.stack([xx, np.full(len(xx), y), np.zeros(len(xx))], 1))
            zone += [z] * len(xx)
            seg += [s] * len(xx)
    P = np.vstack(rows)
    P = np.vstack([P[:1] + [0, 0, 10], P, P[-1:] + [0, 0, 10]])
    zone = ["approach"] + zone + ["depart"]
    seg = [0] + seg + [1]
    poses = np.tile(np.eye(4), (len(P), 1, 1))
    poses[:, :3, :3] = np.diag([1.0, -1.0, -1.0])   # tool z = -world z
    poses[:, :3, 3] = P
    return Path(poses, np.array(seg, np.int32), np.zeros(len(P), np.int32),
                np.array([ZONE_CODE[z] for z in zone], np.int32))


def test_a_lead_that_runs_into_the_rise_is_lifted_clear_and_nothing_else_moves():
    path = two_row_path()
    P0 = path.poses_mm[:, :3, 3]
    zone = np.asarray(path.zone)
    out_first = np.flatnonzero((zone == ZONE_CODE["lead_out"]) & (path.segment == 0))
    assert signed_distance(P0[out_first]).min() < -5.0                 # the tangent lead runs 5+ mm into the part
    new = cleared_leads(path, signed_distance, lead_mm=15.0)
    P = new.poses_mm[:, :3, 3]
    moved = np.linalg.norm(P - P0, axis=1) > 1e-9
    lead_or_self = np.isin(zone, [ZONE_CODE[z] for z in ("lead_in", "lead_out", "self_motion")])
    assert signed_distance(P[lead_or_self]).min() >= 0.0                 # on the part at most, not in it
    assert signed_distance(P[out_first]).min() >= 0.5 * LEAD_CLEAR_MM
    assert not moved[zone == ZONE_CODE["work"]].any()                    # the work stays on the part
    assert np.allclose(new.poses_mm[:, :3, :3], path.poses_mm[:, :3, :3])  # orientations kept
    # the lifted lead rises straight up (against the tool axis); the rise 4.5 mm past the work's end is too close
    # for the cube (c = 47 mm > 3 leads of 15 mm), the square clears it: 5.9 mm at the near pose (closed form:
    # (z - 4.5) / sqrt 2 = 1, within the rounds' convergence), four times that at the far one
    lift = P[out_first] - P0[out_first]
    assert np.allclose(lift[:, :2], 0.0) and (lift[:, 2] > 0).all()
    assert np.isclose(lift[0, 2] / lift[1, 2], 0.5 ** 2)
    assert 4.5 + 0.5 * np.sqrt(2.0) <= lift[0, 2] <= 4.5 + np.sqrt(2.0) + 1e-6
    # the leads on the flat side of the rows, on the part but not in it, stay where they were
    in_first = np.flatnonzero((zone == ZONE_CODE["lead_in"]) & (path.segment == 0))
    assert not moved[in_first].any()


def test_a_self_motion_takes_its_ends_lifts_and_a_clear_path_comes_back_as_it_was():
    path = two_row_path()
    new = cleared_leads(path, signed_distance, lead_mm=15.0)
    zone = np.asarray(path.zone)
    k = np.flatnonzero(zone == ZONE_CODE["self_motion"])
    a, b = k[0] - 1, k[-1] + 1
    d = new.poses_mm[:, :3, 3] - path.poses_mm[:, :3, 3]
    f = np.arange(1, len(k) + 1) / (len(k) + 1)
    blend = (1 - f)[:, None] * d[a] + f[:, None] * d[b]
    assert np.all(d[k, 2] >= blend[:, 2] - 1e-9)                       # at least the blend of its ends' lifts
    assert signed_distance(new.poses_mm[k, :3, 3]).min() >= 0.5 * LEAD_CLEAR_MM
    # every lead clear already: the same object back
    assert cleared_leads(new, signed_distance, lead_mm=15.0, clear_mm=0.5) is new
    # poses not in ``only`` are left alone
    assert cleared_leads(path, signed_distance, lead_mm=15.0, only=np.zeros(len(path), bool)) is path


def test_a_self_motion_whose_chord_crosses_a_ridge_rises_over_it():
    """A ridge 1 mm thin and 8 mm high at y = 18.75 between the transition's last pose and the next lead: every pose
    is clear of it, the straight chord between them is not (it crosses at 2.5 mm); after clearing, the chords
    sampled every 0.1 mm are all out of it."""
    def ridge(P):
        P = np.atleast_2d(P)
        return np.minimum(P[:, 2], np.maximum(np.abs(P[:, 1] - 18.75) - 0.5, P[:, 2] - 8.0))

    path = two_row_path()
    zone = np.asarray(path.zone)
    k = np.flatnonzero(zone == ZONE_CODE["self_motion"])
    chain = np.arange(k[0] - 1, k[-1] + 2)

    def chord_min(p):
        Q = p.poses_mm[chain, :3, 3]
        t = np.linspace(0, 1, 1001)[:, None, None]
        return ridge((Q[:-1] + t * (Q[1:] - Q[:-1])).reshape(-1, 3)).min()

    assert ridge(path.poses_mm[:, :3, 3]).min() >= 0.0 and chord_min(path) < -0.4   # through the ridge
    new = cleared_leads(path, ridge, lead_mm=15.0)
    assert chord_min(new) >= 0.0
    assert np.allclose(new.poses_mm[zone != ZONE_CODE["self_motion"]], path.poses_mm[zone != ZONE_CODE["self_motion"]])


def test_a_lead_whose_chord_to_the_work_cuts_a_bent_edge_is_lifted_over_it():
    """The poses of the first row's lead-out are on the plane, but a 0.3 mm ridge midway between the work's end
    (x = 100) and the lead's first pose (x = 107.5) is in the way of the chord between them."""
    from camtool.path.lead_clearance import CHORD_SLACK_MM

    def ridge_sd(P):
        """mm above the plane z = 0 with a tent 0.3 mm high at x = 103.75 (slope 0.08: the vertical distance)."""
        P = np.atleast_2d(P)
        return P[:, 2] - np.maximum(0.0, 0.3 - 0.08 * np.abs(P[:, 0] - 103.75))

    path = two_row_path()
    P0 = path.poses_mm[:, :3, 3]
    zone = np.asarray(path.zone)
    out_first = np.flatnonzero((zone == ZONE_CODE["lead_out"]) & (path.segment == 0))
    chain = np.r_[out_first[0] - 1, out_first]

    def chord_min(P):
        f = np.linspace(0.0, 1.0, 201)[:, None]
        return min(ridge_sd(P[a] + f * (P[b] - P[a])).min() for a, b in zip(chain[:-1], chain[1:]))

    assert ridge_sd(P0[out_first]).min() >= 0.0 and chord_min(P0) < -0.25   # poses on the part, the chord 0.3 in
    new = cleared_leads(path, ridge_sd, lead_mm=15.0)
    P = new.poses_mm[:, :3, 3]
    moved = np.linalg.norm(P - P0, axis=1) > 1e-9
    assert chord_min(P) >= -CHORD_SLACK_MM - 1e-9
    assert ridge_sd(P[out_first]).min() >= 0.5 * LEAD_CLEAR_MM
    in_second = np.flatnonzero((zone == ZONE_CODE["lead_in"]) & (path.segment == 1))   # crosses the ridge too
    lead = np.isin(zone, [ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]])
    assert set(np.flatnonzero(moved & lead)) == set(out_first) | set(in_second)
    assert not moved[zone == ZONE_CODE["work"]].any()


def test_a_narrow_edge_between_two_millimetre_samples_of_a_lead_chord_is_found():
    """A tent 0.3 mm high and 1.5 mm wide at x = 101, between the work's end (x = 100) and the chord's next sample
    2 mm on (the Vito door's lead-in chord ran 0.097 mm into a bent edge between its 2 mm samples): found and
    lifted over, the chord out of it but for the slack."""
    from camtool.path.lead_clearance import CHORD_SLACK_MM

    def tent_sd(P):
        P = np.atleast_2d(P)
        return P[:, 2] - np.maximum(0.0, 0.3 - 0.4 * np.abs(P[:, 0] - 101.0))

    path = two_row_path()
    P0 = path.poses_mm[:, :3, 3]
    zone = np.asarray(path.zone)
    out_first = np.flatnonzero((zone == ZONE_CODE["lead_out"]) & (path.segment == 0))
    in_second = np.flatnonzero((zone == ZONE_CODE["lead_in"]) & (path.segment == 1))

    def chord_min(P, chain):
        f = np.linspace(0.0, 1.0, 3001)[:, None]
        return min(tent_sd(P[a] + f * (P[b] - P[a])).min() for a, b in zip(chain[:-1], chain[1:]))

    chains = (np.r_[out_first[0] - 1, out_first], np.r_[in_second, in_second[-1] + 1])
    assert tent_sd(P0).min() >= 0.0 and min(chord_min(P0, c) for c in chains) < -0.25
    new = cleared_leads(path, tent_sd, lead_mm=15.0)
    P = new.poses_mm[:, :3, 3]
    assert min(chord_min(P, c) for c in chains) >= -CHORD_SLACK_MM - 1e-9
    moved = np.linalg.norm(P - P0, axis=1) > 1e-9
    lead = np.isin(zone, [ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]])
    assert set(np.flatnonzero(moved & lead)) == set(out_first) | set(in_second)
