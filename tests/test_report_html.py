"""report.html: one self-contained, deterministic page (plotly inline) for ok and failed runs."""
import re
import shutil
import subprocess
from html.parser import HTMLParser

import numpy as np
import pytest

from camtool.plan import plan_path
from camtool.report.redundancy_map import RedundancySettings, redundancy_map
from camtool.report.run_report import plan_metrics
from camtool.report.html import DIV, FAILING_NAME, MAX_WORKPIECE_POINTS, _feed, write_report_html, write_run_html
from camtool.robots import get_robot
from camtool.settings import PlannerSettings, TimingSettings
from camtool.part.surface import Boundary, SpherePatch
from camtool.timing import time_trajectory
from camtool.path.toolpath import Path
from camtool.trajectory import JointPath, Trajectory
from camtool.part.workpiece import Workpiece

from plan_fixtures import sphere_rows

CENTER, RADIUS = np.array([1000.0, 0.0, 100.0]), 600.0
MAX_BYTES = 15 * 1024 * 1024


def _sphere_points(n, seed=0):
    rng = np.random.default_rng(seed)
    az, el = np.radians(rng.uniform(-45, 45, n)), np.radians(rng.uniform(-15, 65, n))
    nrm = np.column_stack([-np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return CENTER + RADIUS * nrm, nrm


def _surface():
    frame = np.array([[-1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]).T
    outer = np.radians([[-40, -10], [40, -10], [40, 60], [-40, 60]])
    return SpherePatch(CENTER, RADIUS, frame, Boundary(outer))


@pytest.fixture(scope="module")
def job():
    """A small seed8 job on the sphere patch: path, plan, timed trajectory, report, redundancy map."""
    robot = get_robot("seed8")
    path = sphere_rows(rows=3, pitch_mm=20.0)
    jp = plan_path(path, robot, PlannerSettings.make())
    tr = time_trajectory(jp, path, robot, TimingSettings.make(tcp_speed_mm_s=100.0))
    report = plan_metrics(path, jp, robot, "seed", 50.0, 100.0)
    report.update(status="ok", tcp_speed_mm_s=100.0, waypoints=len(tr.t_s), slowdowns=[{"first_row": 1}])
    pts, nrm = _sphere_points(3000)
    rmap = redundancy_map(path, robot, jp, RedundancySettings(max_poses=40, track_values=21))
    return dict(report=report, robot=robot, workpiece=Workpiece(pts, nrm), surface=_surface(), path=path,
                joint_path=jp, trajectory=tr, redundancy=rmap)


class _Resources(HTMLParser):
    """Every script src and link href of a page (script bodies are not parsed as markup)."""

    def __init__(self):
        super().__init__()
        self.sources, self.scripts = [], 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "script":
            self.scripts += 1
            if a.get("src"):
                self.sources.append(a["src"])
        if tag == "link" and a.get("href"):
            self.sources.append(a["href"])


def _check_self_contained(text):
    assert 'src="http' not in text and "src='http" not in text
    p = _Resources()
    p.feed(text)
    assert p.scripts >= 2 and p.sources == []          # plotly.js and every figure inline
    assert "Plotly.newPlot" in text and len(text) > 3_000_000   # the plotly.js bundle itself


def test_ok_run_is_self_contained_and_shows_every_part(job, tmp_path):
    f = write_report_html(tmp_path / "out" / "report.html", **job)
    text = f.read_text()
    _check_self_contained(text)
    assert f.stat().st_size <= MAX_BYTES
    for div in DIV.values():
        assert f'id="{div}"' in text
    assert '"sliders"' in text and "robot joints (slider below)" in text       # joints on a slider
    assert "robot link shapes (slider below)" in text     # and the link shapes the check measures
    assert "work: TCP feed" in text and "TCP path length [mm]" in text
    assert "share of limit" in text and "track position [mm]" in text
    assert "max_position_error_mm" in text and "slowdowns" in text     # the summary table
    assert "fitted surface boundary" in text and "workpiece (3000 of 3000 points)" in text
    assert FAILING_NAME not in text                                    # nothing failed


def test_two_writes_are_byte_identical(job, tmp_path):
    a = write_report_html(tmp_path / "a.html", **job).read_bytes()
    b = write_report_html(tmp_path / "b.html", **job).read_bytes()
    assert a == b
    assert not re.search(rb'id="[0-9a-f]{8}-[0-9a-f]{4}-', a)          # no plotly random div ids


def test_feed_is_the_programmed_tcp_speed_on_work(job):
    feed = _feed(job["robot"], job["trajectory"])
    work = (feed["zone"] == 0) & np.isfinite(feed["v"])
    # rows the limits slow run at their own constant feed; the rest at the programmed 100 mm/s
    assert np.percentile(feed["v"][work], 90) == pytest.approx(100.0, rel=0.03)
    assert np.all(feed["v"][work] <= 100.0 * 1.03)
    assert feed["s"][-1] == pytest.approx(np.linalg.norm(np.diff(feed["p"], axis=0), axis=1).sum())


def test_failed_job_marks_the_failing_poses(job, tmp_path):
    path, robot = job["path"], job["robot"]
    failing = [5, 17, 40]
    report = {"robot": robot.name, "status": "infeasible", "reason": "3 poses out of reach",
              "unreachable": [{"index": 40, "xyz_mm": path.poses_mm[40][:3, 3].round(3).tolist()},
                              {"index": 60, "xyz_mm": path.poses_mm[60][:3, 3].round(3).tolist()}]}
    f = write_report_html(tmp_path / "failed.html", report=report, robot=robot, path=path,
                          failing_indices=failing)
    text = f.read_text()
    _check_self_contained(text)
    assert f"{FAILING_NAME} (4)" in text                   # 5, 17, 40 and 60, once each
    assert "robot (zero joint values; no plan)" in text and "No trajectory" in text
    assert f'id="{DIV["feed"]}"' not in text and f'id="{DIV["redundancy"]}"' not in text
    # a failed plan's partial joint path: the unreached rows are marked too
    jp = job["joint_path"]
    reached = jp.reached.copy()
    reached[[5, 17]] = False
    partial = JointPath(jp.q, jp.path_index, jp.zone, jp.position_error_mm, jp.orientation_error_rad, jp.jump,
                        jp.reverse_planned, jp.retract, jp.singular, reached, jp.events)
    text = write_report_html(tmp_path / "partial.html", report=report, robot=robot, path=path, joint_path=partial,
                             failing_indices=failing).read_text()
    assert "not reached (IK) (2)" in text and "robot joints (slider below)" in text


def test_write_run_html_adds_the_redundancy_png(job, tmp_path):
    files = write_run_html(tmp_path, report=job["report"], robot=job["robot"], path=job["path"],
                           joint_path=job["joint_path"], trajectory=job["trajectory"])
    assert [f.name for f in files] == ["report.html", "redundancy_map.png"]
    assert f'id="{DIV["redundancy"]}"' in files[0].read_text()


def test_a_100k_point_job_stays_under_15_mb(job, tmp_path):
    """100k workpiece points, a 100k-pose path, a 100k-waypoint trajectory and many flagged rows."""
    robot = job["robot"]
    n = 100_000
    pts, nrm = _sphere_points(n, seed=1)
    small = job["path"]
    reps = n // len(small) + 1
    poses = np.concatenate([small.poses_mm] * reps)[:n].copy()
    poses[:, :3, 3] += np.repeat(np.arange(reps) * 0.37, len(small))[:n, None]   # no two poses alike
    zone = np.concatenate([small.zone] * reps)[:n]
    path = Path(poses, np.repeat(np.arange(reps), len(small))[:n], np.tile(small.point, reps)[:n], zone)
    jp0 = job["joint_path"]
    q = np.concatenate([jp0.q] * (n // len(jp0.q) + 1))[:n]
    flags = np.zeros(n, bool)
    jp = JointPath(q, np.arange(n), zone, np.zeros(n), np.zeros(n), flags, np.arange(n) % 7 == 0,
                   np.arange(n) % 11 == 0, np.arange(n) % 13 == 0, np.arange(n) % 17 != 0)
    t = np.arange(n) * 0.05
    tr = Trajectory(robot.name, robot.joint_names, robot.prismatic, t, q, np.zeros_like(q), np.zeros_like(q),
                    zone, np.arange(n))
    report = dict(job["report"], points_total=n)
    unreachable = [{"index": int(i), "xyz_mm": poses[i][:3, 3].tolist()} for i in range(0, n, 9)]
    f = write_report_html(tmp_path / "big.html", report=dict(report, unreachable=unreachable), robot=robot,
                          workpiece=Workpiece(pts, nrm), surface=_surface(), path=path, joint_path=jp,
                          trajectory=tr, failing_indices=range(0, n, 5), redundancy=job["redundancy"])
    size = f.stat().st_size
    assert size <= MAX_BYTES, f"{size / 1e6:.1f} MB"
    assert f"workpiece ({MAX_WORKPIECE_POINTS} of {n} points)" in f.read_text()


def _browser():
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_browser() is None, reason="no headless browser: neither 'chromium' nor 'chromium-browser' "
                                               "is on PATH (scripts/setup.sh installs Debian's chromium as root)")
def test_the_page_renders_in_a_headless_browser(job, tmp_path):
    page = write_report_html(tmp_path / "report.html", **job)
    shot = tmp_path / "shot.png"
    cmd = [_browser(), "--headless", "--disable-gpu", "--no-sandbox", "--enable-unsafe-swiftshader",
           "--hide-scrollbars", f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}", "--dump-dom",
           "--window-size=1200,900", "--virtual-time-budget=8000", "--enable-logging=stderr", "--v=0",
           page.as_uri()]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    console = [ln for ln in r.stderr.splitlines() if ":CONSOLE" in ln and "WebGL" not in ln]
    errors = [ln for ln in console if "Uncaught" in ln or "Error" in ln or "ERROR:CONSOLE" in ln]
    assert not errors, "\n".join(errors)
    for div in DIV.values():                      # plotly drew every figure
        assert re.search(rf'<div id="{div}" class="[^"]*js-plotly-plot', r.stdout), div
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)
    assert img.shape[0] >= 800 and img.shape[1] >= 1100
    assert img[..., :3].std() > 0.05                              # not a blank page
    assert (img[..., :3].min(axis=2) < 0.9).mean() > 0.01         # some ink


def test_the_feed_shown_keeps_each_bins_first_lowest_value():
    """``_lowest_per_bin`` (vectorised) picks what a loop over the bins picks: each bin's first lowest feed,
    NaN ignored, a bin of NaN only shown at its first sample."""
    from camtool.report.html import _lowest_per_bin

    rng = np.random.default_rng(3)
    v = np.round(rng.random(10_007) * 50, 0)   # ties within a bin: the first is kept
    v[100:260] = np.nan                          # whole bins of NaN, and bins partly NaN
    v[-3:] = np.nan
    edges = np.round(np.linspace(0, len(v), 800 + 1)).astype(int)
    loop = np.array([a + int(np.nanargmin(v[a:b])) if np.isfinite(v[a:b]).any() else a
                     for a, b in zip(edges[:-1], edges[1:]) if b > a])
    assert np.array_equal(_lowest_per_bin(v, edges), loop)
