"""Timing of the motion check: ``.venv/bin/python benchmarks/motion_check_speed.py [--samples N] [--points N]``.

A synthetic program on the seed arm (150 mm tool): an ~800 s raster-like
sweep of the track with small wrist motions, waypoints every 40 ms, 80 % work,
over a sphere patch (R = 2 m) laid under the TCP's path, as a mesh and as
a point cloud. No planner is involved: the motion is made in joint space.
Prints the part build time, the check time and samples per second; then the
same check with the collision world (``camtool.collision``: the arm's link
shapes, the carriage, the tool, self-collision and two obstacles, a table
300 mm under the TCP's lowest point and a post beside its path) and the time
of its cell pass alone.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def synthetic(samples: int, points: int, seed: int = 0):
    import trimesh

    from camtool.robots import get_robot
    from camtool.path.toolpath import ZONE_CODE
    from camtool.transforms import matrix_from_xyz_rpy
    from camtool.part.workpiece import Workpiece
    from camtool.motion.fk_batch import BatchFK

    robot = get_robot("seed8").with_placement(tool_T_mm=matrix_from_xyz_rpy([0, 0, 150], [0, 0, 0]))
    q0 = np.array([0.0, 0.3, 0.2, -0.4, 0.8, 0.1, -0.9, 0.2])
    duration = samples * 0.004
    t = np.arange(0.0, duration, 0.04)
    rng = np.random.default_rng(seed)
    q = np.tile(q0, (len(t), 1))
    q[:, 0] = 300.0 * np.sin(2 * np.pi * t / 40.0)           # track sweeps
    for j in range(1, 8):                                   # slow small arm and wrist motions
        q[:, j] += 0.01 * np.sin(2 * np.pi * t / rng.uniform(20, 60) + rng.uniform(0, 6))
    zone = np.where((t % 50.0) < 40.0, ZONE_CODE["work"], ZONE_CODE["self_motion"])
    fk = BatchFK(robot)(q)
    tool_z = fk.tcp_R[:, :, 2].mean(axis=0)
    tool_z /= np.linalg.norm(tool_z)
    R = 2000.0
    center = fk.tcp.mean(axis=0) + R * tool_z       # the TCP path runs about on the sphere
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=R)
    keep = sphere.triangles_center @ -tool_z > R * np.cos(np.radians(15))
    cap = trimesh.Trimesh(sphere.vertices + center, sphere.faces[keep], process=False)
    cap.remove_unreferenced_vertices()
    pts, face = trimesh.sample.sample_surface(cap, points, seed=seed)
    mesh = Workpiece(np.asarray(pts), cap.face_normals[face], np.asarray(cap.faces), "bench",
                     vertices_mm=np.asarray(cap.vertices))
    cloud = Workpiece(np.asarray(pts), cap.face_normals[face])
    work = zone == ZONE_CODE["work"]
    hint = fk.tcp[work], -fk.tcp_R[work][:, :, 2]
    return robot, t, q, zone, mesh, cloud, hint


def _two_obstacle_world(robot, q):
    """The arm's collision world with a table under the motion and a post beside it."""
    from camtool.collision import CellSettings, CollisionWorld
    from camtool.collision.shapes import WORLD, Body
    from camtool.motion.fk_batch import BatchFK

    fk = BatchFK(robot)(q[:: max(1, len(q) // 2000)])
    pts = np.concatenate([fk.joint_origins.reshape(-1, 3), fk.tcp])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    table = np.eye(4)
    table[:3, 3] = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2] - 150.0]   # 130 mm under the lowest origin
    post = np.eye(4)
    post[:3, 3] = [hi[0] + 200.0, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2]     # 160 mm beyond the farthest
    obstacles = (Body("table", "obstacle", WORLD, "box", (1500.0, 2500.0, 40.0), table),
                 Body("post", "obstacle", WORLD, "cylinder", (40.0, 1500.0), post))
    return CollisionWorld(robot, CellSettings(obstacles=obstacles), tool_radius_mm=25.0)


def main(argv=None) -> None:
    from camtool.motion.check import MotionCheckSettings, check_motion
    from camtool.motion.geometry import PartGeometry

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200_000)
    ap.add_argument("--points", type=int, default=100_000)
    args = ap.parse_args(argv)
    robot, t, q, zone, mesh, cloud, hint = synthetic(args.samples, args.points)
    for name, wp in (("mesh", mesh), ("cloud", cloud)):
        clock = time.perf_counter()
        part = PartGeometry.from_workpiece(wp, *hint)
        build = time.perf_counter() - clock
        rep = check_motion(t, q, zone, robot, part, MotionCheckSettings())
        print(f"{name:5s}: {part.describe()}")
        print(f"       build {build:.2f} s; check {rep.check_seconds:.2f} s for {rep.samples} samples "
              f"= {rep.samples / rep.check_seconds:,.0f} samples/s; max penetration "
              f"{rep.max_penetration_mm:.2f} mm, work deviation {rep.work_deviation_mm:.2f} mm, "
              f"{len(rep.findings)} findings")
        if name == "mesh":
            world = _two_obstacle_world(robot, q)
            cell = check_motion(t, q, zone, robot, part, MotionCheckSettings(), world=world)
            print(f"       with the collision world ({len(world.pairs)} pairs, 2 obstacles): check "
                  f"{cell.check_seconds:.2f} s, of which the cell pass {cell.cell['seconds']:.2f} s "
                  f"({cell.cell['evaluations']} coal distances); closest pair "
                  + min(((p['min_distance_mm'], p['a'], p['b']) for p in cell.cell_pairs),
                        key=lambda x: x[0]).__repr__())


if __name__ == "__main__":
    main()
