"""camtool.process.footprint: unit volume, kernels and the straight-pass profile."""
import math

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.process.footprint import Footprint
from camtool.settings import ProcessSettings


@pytest.mark.parametrize("profile", ["flat", "parabolic", "gaussian", "table"])
def test_density_has_unit_volume(profile):
    fp = Footprint(profile, 20.0, sigma_mm=5.0, table=((0.0, 1.0), (10.0, 0.8), (20.0, 0.0)))
    r = np.linspace(0, 20, 20001)
    vol = np.trapezoid(fp.density(r) * 2 * math.pi * r, r)
    assert vol == pytest.approx(1.0, rel=1e-3)
    assert fp.density(np.array([20.5]))[0] == 0.0


@pytest.mark.parametrize("profile", ["flat", "parabolic", "gaussian"])
def test_kernel_sums_to_one_and_pass_profile_integrates_to_one(profile):
    fp = Footprint(profile, 15.0, sigma_mm=4.0)
    k = fp.kernel(1.0)
    assert k.sum() == pytest.approx(1.0) and k.shape[0] % 2 == 1
    assert np.allclose(k, k[::-1, ::-1])
    y = np.linspace(-15, 15, 3001)
    assert np.trapezoid(fp.pass_profile(y), y) == pytest.approx(1.0, rel=2e-3)


def test_parabolic_pass_profile_closed_form():
    fp = Footprint("parabolic", 10.0)
    # at y = 0: integral of 2/(pi a^2) (1 - x^2/a^2) over -a..a = 8 / (3 pi a)
    assert fp.pass_profile(0.0) == pytest.approx(8 / (3 * math.pi * 10.0))


def test_settings_defaults_from_the_tool_and_bad_table():
    s = ProcessSettings.make(tool_radius_mm=30.0, kind="polish")
    assert s.diameter_mm == 60.0 and s.grid_mm == pytest.approx(2.4) and s.gaussian_sigma_mm == 10.0
    with pytest.raises(BadInput, match="profile_radius_mm"):
        ProcessSettings.make(kind="polish", profile="table", profile_radius_mm=[0.0], profile_value=[1.0])
    with pytest.raises(BadInput, match="beyond the footprint"):
        ProcessSettings.make(kind="polish", diameter_mm=20, profile="table", profile_radius_mm=[0.0, 15.0],
                             profile_value=[1.0, 0.5])
    with pytest.raises(BadInput, match="process.kind"):
        ProcessSettings.make(kind="buff")


@pytest.mark.parametrize("profile", ["flat", "parabolic"])
def test_cell_kernel_rows_integrate_to_the_pass_profile(profile):
    # cells 2 mm along u, 0.1 mm across: each row of the kernel summed along u is the chord integral of the
    # density over that row (Footprint.pass_profile, closed form, averaged over the row's height)
    fp = Footprint(profile, 25.0)
    du, dv = 2.0, 0.1
    k = fp.cell_kernel(du, dv, 0.02)
    assert k.sum() == pytest.approx(1.0)
    nv = (k.shape[0] - 1) // 2
    y = np.arange(-nv, nv + 1) * dv
    rows = k.sum(axis=1) / dv
    closed = fp.pass_profile(y[:, None] + (np.arange(50) + 0.5 - 25) / 50 * dv).mean(axis=1)  # over each row
    assert np.abs(rows - closed).max() < 0.01 * closed.max()


@pytest.mark.parametrize("profile", ["flat", "parabolic", "gaussian"])
def test_segment_shape_is_the_mean_of_the_profile_along_the_segment(profile):
    """Against a dense midpoint sum along each segment (20 000 points): segments through, into, past and beside
    the footprint, and a point (zero length)."""
    fp = Footprint(profile, 15.0, 6.0)
    rng = np.random.default_rng(1)
    start = rng.uniform(-25, 25, (200, 2))
    step = rng.uniform(-20, 20, (200, 2))
    step[:5] = 0.0
    t = (np.arange(20000) + 0.5) / 20000
    pts = start[:, None, :] + t[None, :, None] * step[:, None, :]
    dense = fp.shape(np.linalg.norm(pts, axis=-1)).mean(axis=1)
    got = fp.segment_shape(np.sum(step * step, 1), np.sum(start * step, 1), np.sum(start * start, 1))
    assert np.abs(got - dense).max() < (2e-4 if profile == "flat" else 1e-4)
    assert (dense > 0.05).sum() > 50 and (dense == 0).sum() > 5   # inside and outside both tried
