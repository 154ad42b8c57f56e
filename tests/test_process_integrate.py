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
