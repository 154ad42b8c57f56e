"""The tool-axis tilt (camtool.path.axis_tilt) against a closed-form part: a floor with a wall rising beside it.

The part: the floor z <= 0 and a wall x <= 0 up to z = H. Rows on the floor run along y at a distance d from
the wall, the tool along the normal (z down into the floor). The bodies are the motion check's on the IRB2400
with a 150 mm polisher (``camtool.motion.tool_bodies``): the tool (radius 25 mm, 30..150 mm behind the TCP)
and the wrist (radius 60 mm, 150..235 mm behind it). Tilted away from the wall by a, the wrist's nearest point
to the wall is 150 mm up the axis: it clears the wall by ``clear_mm`` from a = asin((60 + clear - d) / 150)
(the independent reference, closed form).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from camtool.motion.tool_bodies import tool_axis_bodies
from camtool.path.axis_tilt import AxisBody, AxisTiltSettings, TiltRefused, blended, body_points, tilted_axes
from camtool.path.toolpath import ZONE_CODE, Path
from camtool.robots import get_robot
from camtool.transforms import matrix_from_xyz_rpy

H_MM = 400.0
BODIES = (AxisBody("tool", (0.0, 0.0, -150.0), (0.0, 0.0, -30.0), 25.0),
          AxisBody("wrist (j5-flange)", (0.0, 0.0, -235.0), (0.0, 0.0, -150.0), 60.0))


def wall_sd(P: np.ndarray) -> np.ndarray:
    """Signed distance (mm, + in front) to the floor z <= 0 united with the wall x <= 0, z <= H."""
    P = np.asarray(P, float)
    floor = P[:, 2]
    q = np.stack([P[:, 0], P[:, 2] - H_MM], axis=1)
    wall = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
    return np.minimum(floor, wall)


def floor_rows(distances_mm, half_mm: float = 100.0, pitch_mm: float = 10.0) -> Path:
    """Work rows along y on the floor at each distance from the wall, in S order, tool z into the floor."""
    R = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])   # columns x, y, z: z down, right-handed
    poses, seg, point = [], [], []
    y = np.arange(-half_mm, half_mm + 1e-9, pitch_mm)
    for i, d in enumerate(distances_mm):
        for j, yy in enumerate(y if i % 2 == 0 else y[::-1]):
            T = np.eye(4)
            T[:3, :3] = R
            T[:3, 3] = (d, yy, 0.0)
            poses.append(T)
            seg.append(i)
            point.append(j + 1)
    n = len(poses)
    return Path(np.array(poses), np.array(seg), np.array(point), np.full(n, ZONE_CODE["work"]))


def clearance(path: Path) -> np.ndarray:
    """(poses,) the least clearance of the bodies (mm), measured directly on the path's frames."""
    pts, rad, _ = body_points(BODIES)
    R, t = path.poses_mm[:, :3, :3], path.poses_mm[:, :3, 3]
    world = np.einsum("nij,pj->npi", R, pts) + t[:, None, :]
    return (wall_sd(world.reshape(-1, 3)).reshape(len(path), -1) - rad).min(axis=1)


def axis_turns_deg(path: Path) -> np.ndarray:
    z = path.poses_mm[:, :3, 2]
    return np.degrees(np.arccos(np.clip(np.sum(z[1:] * z[:-1], axis=1), -1, 1)))


def test_the_bodies_are_the_motion_checks_on_the_irb2400():
    robot = get_robot("irb2400").with_placement(np.eye(4), matrix_from_xyz_rpy([0, 0, 150], [0, 0, 0]))
    got = tool_axis_bodies(robot)
    assert [b.name for b in got] == [b.name for b in BODIES]
    for g, b in zip(got, BODIES):
        assert np.allclose(g.a_mm, b.a_mm, atol=1e-6) and np.allclose(g.b_mm, b.b_mm, atol=1e-6)
        assert g.radius_mm == b.radius_mm


def test_a_wall_beside_the_rows_is_cleared_by_the_least_tilt_away_from_it():
    s = AxisTiltSettings()
    path = floor_rows([300.0, 200.0, 20.0, 200.0])
    assert clearance(path)[path.segment == 2].min() < -30.0        # without the tilt the wrist is in the wall
    out, fig = tilted_axes(path, wall_sd, BODIES, s)
    assert (clearance(out) >= s.clear_mm - 1e-6).all()
    assert np.array_equal(out.poses_mm[:, :3, 3], path.poses_mm[:, :3, 3])   # the TCP stays on the surface
    z = out.poses_mm[:, :3, 2]
    tilt_deg = np.degrees(np.arccos(np.clip(-z[:, 2], -1, 1)))
    need = math.degrees(math.asin((60.0 + s.clear_mm - 20.0) / 150.0))
    row = path.segment == 2
    assert need <= tilt_deg[row].min() <= need + math.degrees(s.step_rad) + 1e-6
    assert (-z[row, 0] > 0).all() and np.allclose(z[row, 1], 0.0, atol=1e-9)   # the axis behind turns off the wall
    assert axis_turns_deg(out).max() <= math.degrees(s.turn_rad) + 1e-6
    assert np.array_equal(out.poses_mm[path.segment == 0], path.poses_mm[path.segment == 0])   # far rows untouched
    assert fig.poses_needing_tilt == row.sum() and fig.max_tilt_deg == pytest.approx(tilt_deg.max())
    assert fig.work_poses_tilted == fig.poses_tilted == int((tilt_deg > 1e-9).sum()) > row.sum()


def test_a_path_already_clear_comes_back_as_it_was():
    path = floor_rows([300.0, 200.0])
    out, fig = tilted_axes(path, wall_sd, BODIES)
    assert out is path and fig.poses_tilted == 0


def test_off_switch_and_only():
    path = floor_rows([20.0])
    assert tilted_axes(path, wall_sd, BODIES, AxisTiltSettings(max_rad=0.0))[0] is path
    assert tilted_axes(path, wall_sd, BODIES, only=np.zeros(len(path), bool))[0] is path


def test_a_tilt_beyond_the_maximum_is_refused_in_one_line():
    path = floor_rows([20.0])
    with pytest.raises(TiltRefused) as e:
        tilted_axes(path, wall_sd, BODIES, AxisTiltSettings(max_rad=math.radians(10.0)))
    msg = str(e.value)
    need = math.degrees(math.asin(41.0 / 150.0))
    assert "\n" not in msg and "segment 0" in msg and "raster.axis_tilt_max_deg = 10" in msg
    assert "wrist (j5-flange) is" in msg and f"would need {math.ceil(need):.0f} deg" in msg


def test_blending_keeps_each_need_and_the_turn_between_neighbours():
    rng = np.random.default_rng(3)
    N = 200
    z = np.tile([0.0, 0.0, -1.0], (N, 1))
    need = np.zeros((N, 3))
    k = rng.choice(N, 12, replace=False)
    need[k, 0] = np.radians(rng.uniform(2, 30, 12))                 # about x: all one direction
    out = blended(need, z, math.radians(2.0))
    theta = np.linalg.norm(out, axis=1)
    assert (theta[k] >= np.linalg.norm(need[k], axis=1) - 1e-12).all()
    assert np.degrees(np.abs(np.diff(theta))).max() <= 2.0 + 1e-9
    assert np.allclose(out[:, 2], 0.0)


def test_off_the_surface_the_bodies_keep_the_clearance_asked():
    path = floor_rows([60.0])
    assert clearance(path).min() == pytest.approx(0.0, abs=1e-9)      # the wrist touches the wall: no tilt on work
    assert tilted_axes(path, wall_sd, BODIES, AxisTiltSettings(off_surface_mm=5.0))[0] is path
    lifted = np.array(path.poses_mm)
    lifted[:, 2, 3] = 10.0                                            # a transition 10 mm above the floor
    moving = replace(path, poses_mm=lifted, zone=np.full(len(path), ZONE_CODE["self_motion"]))
    s = AxisTiltSettings(off_surface_mm=5.0)
    out, fig = tilted_axes(moving, wall_sd, BODIES, s)
    assert (clearance(out) >= 5.0 + s.clear_mm - 1e-6).all() and fig.work_poses_tilted == 0
    need = math.degrees(math.asin(6.0 / 150.0))
    z = out.poses_mm[:, :3, 2]
    assert need <= np.degrees(np.arccos(-z[:, 2])).min() <= need + math.degrees(s.step_rad) + 1e-6
