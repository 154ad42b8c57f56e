"""Joint paths for the timing tests: smooth seed8 curves, TCP poses from FK."""
import numpy as np

from camtool.robots import get_robot
from camtool.path.toolpath import ZONE_CODE, Path
from camtool.trajectory import JointPath

BASE_RAD = np.radians([0, 30, 10, 60, 5, 40, 10])


def seed8():
    return get_robot("seed8")


def _curve(u, phase, track_mm):
    q = np.zeros((len(u), 8))
    q[:, 0] = track_mm * u + 20 * np.sin(3 * u + phase)
    for j in range(1, 8):
        q[:, j] = BASE_RAD[j - 1] + np.radians(6) * np.sin(np.pi * u * (1 + 0.1 * j) + phase + j)
    return q


def _even_pitch(robot, phase, n, pitch_mm, track_mm):
    u = np.linspace(0, 1, 2001)
    qq = _curve(u, phase, track_mm)
    p = np.array([robot.fk_tcp(x)[:3, 3] for x in qq])
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    return _curve(np.interp(np.arange(n) * pitch_mm, s, u), phase, track_mm)


def two_runs(robot, n=120, pitch_mm=3.0, track_mm=400.0):
    """Work segment 0, two self-motion poses with a large joint change, work segment 1."""
    qa = _even_pitch(robot, 0.0, n, pitch_mm, track_mm)
    qb = _even_pitch(robot, 1.0, n, pitch_mm, track_mm)
    qb[:, 4] += np.radians(50)
    mid = qa[-1] + (qb[0] - qa[-1]) * np.array([0.3, 0.7])[:, None]
    mid[0, 2] += 0.2
    q = np.vstack([qa, mid, qb])
    zone = np.array([ZONE_CODE["work"]] * n + [ZONE_CODE["self_motion"]] * 2 + [ZONE_CODE["work"]] * n)
    seg = np.array([0] * (n + 1) + [1] * (n + 1))
    return joint_path_and_path(robot, q, zone, seg)


def transition_path(robot, n=60, k=6):
    """Two work runs joined by k self-motion poses on a smooth arc (5 deg steps), like a raster U-turn."""
    jp, _ = two_runs(robot, n=n)
    qa = jp.q[:n]
    step = np.zeros(8)
    step[0], step[1], step[4] = 30.0, np.radians(3), np.radians(4)
    mid = qa[-1] + np.arange(1, k + 1)[:, None] * step + np.sin(np.linspace(0, np.pi, k))[:, None] * \
        np.r_[0, 0, np.radians(2), 0, 0, 0, 0, 0]
    qb = jp.q[n + 2:] - jp.q[n + 2] + qa[-1] + (k + 1) * step
    q = np.vstack([qa, mid, qb])
    zone = np.array([ZONE_CODE["work"]] * n + [ZONE_CODE["self_motion"]] * k + [ZONE_CODE["work"]] * len(qb))
    seg = np.array([0] * (n + k // 2) + [1] * (len(q) - n - k // 2))
    return joint_path_and_path(robot, q, zone, seg)


def retract_path(robot, n=60):
    """A work run, a retract (track -200 mm, then a wrist turn: two inserted poses) and a work run.

    Returns (joint path, path, q of the first retract pose).
    """
    jp, _ = two_runs(robot, n=n)
    q = jp.q[: 2 * n + 2]
    qa, qb = q[:n], q[n + 2:]
    out = qa[-1].copy()
    out[0] -= 200.0
    turn = out.copy()
    turn[4] += 0.8
    back = qa[-1].copy()
    back[4] += 0.8
    qb = qb - qb[0] + back
    qq = np.vstack([qa, out, turn, qb])
    zone = np.array([ZONE_CODE["work"]] * n + [ZONE_CODE["retract"]] * 2 + [ZONE_CODE["work"]] * len(qb))
    seg = np.zeros(len(qq), int)
    pidx = np.r_[np.arange(n), -1, -1, np.arange(n, n + len(qb))]
    jp2, path2 = joint_path_and_path(robot, qq, zone, seg, pidx)
    return jp2, path2, out


def joint_path_and_path(robot, q, zone, seg, path_index=None):
    """A JointPath for q and a Path whose poses are the TCP poses by FK (world = base frame)."""
    n = len(q)
    pidx = np.arange(n) if path_index is None else np.asarray(path_index)
    on = pidx >= 0
    poses = np.array([robot.base_T_mm @ robot.fk_tcp(x) for x in q[on]])
    path = Path(poses, np.asarray(seg)[on], np.arange(on.sum()), np.asarray(zone)[on])
    pidx = np.where(on, np.cumsum(on) - 1, -1)
    f = np.zeros(n, bool)
    jp = JointPath(q, pidx, np.asarray(zone), np.zeros(n), np.zeros(n), f, f, ~on, f, ~f)
    return jp, path


def tcp_speed_mm_s(robot, t, q):
    """TCP speed between consecutive samples, by FK."""
    p = np.array([robot.fk_tcp(x)[:3, 3] for x in q])
    return np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)
