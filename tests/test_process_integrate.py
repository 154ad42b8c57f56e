"""camtool.process.integrate: the map of a TCP track against the closed form; convolution = direct sums."""
import math

import numpy as np
import pytest

from camtool.process.footprint import Footprint
from camtool.process.integrate import process_map
from camtool.settings import ProcessSettings
from camtool.part.surface import Boundary, PlaneSurface, SpherePatch


def plate(w=300.0, h=200.0):
    b = Boundary(np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]]))
    return PlaneSurface(np.zeros(3), np.array([0, 0, 1.0]), np.array([1, 0, 0.0]), np.array([0, 1, 0.0]), b)


def straight_pass(feed=100.0, dt=0.004, y=0.3, lift=0.0):
    t = np.arange(0, 400 / feed, dt)
    return t, np.column_stack([-200 + feed * t, np.full_like(t, y), np.full_like(t, lift)])


@pytest.mark.parametrize("profile", ["flat", "parabolic"])
@pytest.mark.parametrize("method", ["convolution", "direct"])
def test_straight_pass_matches_the_closed_form(profile, method):
    s = ProcessSettings.make(kind="polish", profile=profile, diameter_mm=40)
    t, tcp = straight_pass()
    pm = process_map(s, plate(), t, tcp, method=method)
    per_mm = s.preston_coefficient_per_pa * s.force_n * 1e-3 * 1e12  # um * mm^2 per mm of travel
    iu = int(np.argmin(np.abs(pm.grid.u)))
    closed = per_mm * Footprint.from_settings(s).pass_profile(pm.grid.v - 0.3)
    band = np.abs(pm.grid.v - 0.3) < 20
    assert pm.values[band, iu].mean() == pytest.approx(closed[band].mean(), rel=0.01)
    assert pm.method == method and pm.contact_length_mm == pytest.approx(400.0 - 100 * 0.004, abs=1.0)


def test_off_the_surface_does_nothing_and_volume_is_conserved():
    s = ProcessSettings.make(kind="paint", diameter_mm=40, contact_tol_mm=1.0)
    t, tcp = straight_pass(lift=5.0)
    assert process_map(s, plate(), t, tcp).values.max() == 0.0
    t, tcp = straight_pass(feed=50.0)
    pm = process_map(s, plate(w=600, h=300), t, tcp)
    t_on = pm.contact_time_s
    volume_um_mm2 = float(np.sum(pm.values * pm.grid.area_mm2))
    assert volume_um_mm2 == pytest.approx(s.deposition_mm3_s * t_on * 1e3, rel=1e-6)


def test_dwell_counts_a_tool_at_rest():
    s = ProcessSettings.make(kind="paint", diameter_mm=40, relative_speed_m_s=0.0)
    t = np.arange(0, 2.0, 0.004)
    tcp = np.zeros((len(t), 3))
    pm = process_map(s, plate(), t, tcp)
    assert pm.values.max() > 0 and pm.contact_time_s == pytest.approx(t[-1])


def test_inspect_counts_passes():
    s = ProcessSettings.make(kind="inspect", diameter_mm=40)
    t, a = straight_pass(y=0.0)
    _, b = straight_pass(y=10.0)
    gap = np.column_stack([np.full(10, 200.0), np.zeros(10), np.full(10, 50.0)])  # lifted between passes
    tcp = np.vstack([a, gap, b[::-1]])
    tt = np.arange(len(tcp)) * 0.004
    pm = process_map(s, plate(), tt, tcp)
    iu = int(np.argmin(np.abs(pm.grid.u)))
    iv = int(np.argmin(np.abs(pm.grid.v - 5.0)))
    assert pm.values[iv, iu] == 2
    assert pm.values[int(np.argmin(np.abs(pm.grid.v + 15.0))), iu] == 1


@pytest.mark.parametrize("method", ["auto", "direct"])
def test_sphere_maps_conserve_volume(method):
    R = 600.0
    frame = np.eye(3)
    outer = np.radians(np.array([[-20, -10], [20, -10], [20, 30], [-20, 30]], float))
    sph = SpherePatch(np.zeros(3), R, frame, Boundary(outer))
    s = ProcessSettings.make(kind="polish", diameter_mm=40, profile="parabolic")
    u = np.linspace(-0.3, 0.3, 3000)
    v = np.full_like(u, math.radians(10.0))
    tcp = sph.point_mm(u, v)
    t = np.arange(len(u)) * 0.004
    pm = process_map(s, sph, t, tcp, method=method)
    assert pm.method == ("row-convolution" if method == "auto" else "direct")
    volume = float(np.sum(pm.values * pm.grid.area_mm2))
    per_mm = s.preston_coefficient_per_pa * s.force_n * 1e-3 * 1e12
    assert volume == pytest.approx(per_mm * pm.contact_length_mm, rel=1e-6)


def test_sphere_row_convolution_matches_direct_sums():
    R = 500.0
    outer = np.radians(np.array([[-20, -10], [20, -10], [20, 50], [-20, 50]], float))
    sph = SpherePatch(np.zeros(3), R, np.eye(3), Boundary(outer))
    s = ProcessSettings.make(kind="polish", diameter_mm=40, profile="flat")
    u = np.linspace(-0.3, 0.3, 3000)
    lifted = np.full((5, 3), 2000.0)  # off the part between the passes
    tcp = np.vstack([sph.point_mm(u, np.full_like(u, math.radians(5.0))), lifted,
                     sph.point_mm(u, np.full_like(u, math.radians(40.0)))])
    t = np.arange(len(tcp)) * 0.004
    a = process_map(s, sph, t, tcp).values
    b = process_map(s, sph, t, tcp, method="direct").values
    on = b > 0.05 * b.max()
    assert np.sqrt(np.mean((a[on] - b[on]) ** 2)) / b[on].mean() < 0.02


def test_across_rows_is_normal_to_the_travel():
    from camtool.process.integrate import across_rows_mm, contacts_from_tcp

    s = ProcessSettings.make(kind="polish", diameter_mm=40)
    d = np.array([math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0])
    t = np.arange(0, 3.0, 0.004)
    c = contacts_from_tcp(s, plate(), t, (t * 100.0)[:, None] * d[None, :] - 100 * d)
    n = across_rows_mm(plate(), c)
    assert abs(n @ d[:2]) < 1e-9 and np.linalg.norm(n) == pytest.approx(1.0)


def test_contacts_spread_along_their_path_do_not_alias_against_the_cells():
    from camtool.process.grid import map_grid, refined
    from camtool.process.integrate import Contacts, _along_path, _bin_bilinear

    g = refined(map_grid(plate(100, 20), 1.3, 0.0), 1, 10)
    u = np.arange(-40.0, 40.0, 1.0) + 0.5          # a contact per mm, 1.3 mm cells: the spacings beat
    n = len(u)
    c = Contacts(np.column_stack([u, np.full(n, 0.01)]), np.zeros((n, 3)), np.tile([0, 0, 1.0], (n, 1)),
                 np.ones(n), np.zeros(n, int), np.full(n, 0.01), np.ones(n))
    per_cell = lambda uv, w: _bin_bilinear(g, uv, w).sum(axis=0)  # noqa: E731  (amount per column of cells)
    inner = np.abs(g.u) < 30
    as_points = per_cell(c.uv, c.amount)[inner] / g.du
    spread = per_cell(*_along_path(g, c))[inner] / g.du
    assert np.ptp(as_points) > 0.1                                # points: the columns get 1 or 2 contacts
    assert np.abs(spread - 1.0).max() < 0.01                      # the stretches: 1 per mm in every column
