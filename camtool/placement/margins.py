"""How much room a planned run leaves: joint limits, reach and singularities (for report.json).

``reach_margins(path, joint_path, robot)`` looks at the planned configurations
of the work poses (zone ``work``, reached) and gives

- ``joint_limit``: the smallest distance of any joint to its nearer limit, as
  a share of that joint's range (0 at a limit, 0.5 at mid-range), which joint,
  its value and limit (deg, or mm for the track) and where;
- ``reach``: the largest shoulder-wrist distance used, as a share of the
  straight-elbow distance (``kinematics``: set by the elbow joint alone), and
  the reach margin ``100 - used`` in percent; None for robots without
  closed-form families;
- ``manipulability``: along the work path, Yoshikawa's ``sqrt(det(J J^T))`` of
  the TCP Jacobian (base frame, mm and rad rows, as the redundancy map) and the
  inverse condition number of the Jacobian scaled as the planner weighs it
  (``kinematics.dexterity``: 0 at a singularity, 1 isotropic): min and median.

At most ``max_rows`` work rows are evaluated (evenly spread) so the figures
cost well under a second on any job.
"""
from __future__ import annotations

import numpy as np

from ..path.toolpath import WORK
from .kinematics import ClosedForm, dexterity, yoshikawa

MAX_ROWS = 4000


def _spread(n: int, m: int) -> np.ndarray:
    if n <= m:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, m)).astype(int))


def _edge(robot, i: int, x: float) -> float:
    return float(x) if robot.prismatic[i] else float(np.degrees(x))


def reach_margins(path, joint_path, robot, max_rows: int = MAX_ROWS, orientation_mm: float = 200.0,
                  track_scale_mm: float = 500.0) -> dict:
    """Joint-limit, reach and manipulability margins of a planned run's work poses (module doc)."""
    jp = joint_path
    rows = np.flatnonzero((jp.zone == WORK) & (jp.path_index >= 0) & np.asarray(jp.reached, bool))
    if len(rows) == 0:
        return {"work_rows": 0, "joint_limit": None, "reach": None, "manipulability": None}
    q = np.asarray(jp.q[rows], float)
    L = robot.limits
    span = L.upper - L.lower
    share = np.minimum(q - L.lower, L.upper - q) / span              # (rows, dof)
    r, j = np.unravel_index(int(np.argmin(share)), share.shape)
    nearer_upper = (L.upper[j] - q[r, j]) < (q[r, j] - L.lower[j])
    unit = "mm" if robot.prismatic[j] else "deg"
    joint_limit = {
        "min_share": round(float(share[r, j]), 4), "joint": robot.joint_names[j],
        "value": round(_edge(robot, j, q[r, j]), 3),
        "limit": round(_edge(robot, j, L.upper[j] if nearer_upper else L.lower[j]), 3), "unit": unit,
        "path_index": int(jp.path_index[rows[r]]),
        "per_joint_min_share": {n: round(float(v), 4) for n, v in zip(robot.joint_names, share.min(axis=0))},
    }
    model = ClosedForm.for_robot(robot)
    reach = None
    if model is not None:
        used = model.reach_used_q(q)
        k = int(np.argmax(used))
        reach = {"max_used_pct": round(100.0 * float(used[k]), 2),
                 "margin_pct": round(100.0 * (1.0 - float(used[k])), 2),
                 "median_used_pct": round(100.0 * float(np.median(used)), 2),
                 "max_reach_mm": round(model.elbow.d_max, 3),
                 "path_index": int(jp.path_index[rows[k]]),
                 "xyz_mm": [round(float(x), 3) for x in path.poses_mm[int(jp.path_index[rows[k]])][:3, 3]]}
    pick = _spread(len(rows), max_rows)
    if model is not None:
        J = model.jacobian(q[pick])
    else:
        J = np.array([robot.jacobian(x, tcp=True) for x in q[pick]])
    w = yoshikawa(J)
    dex = dexterity(J, robot.prismatic, orientation_mm, track_scale_mm)
    k = int(np.argmin(dex))
    manip = {"yoshikawa_min": float(f"{w.min():.6g}"), "yoshikawa_median": float(f"{np.median(w):.6g}"),
             "dexterity_min": round(float(dex.min()), 5), "dexterity_median": round(float(np.median(dex)), 5),
             "dexterity_min_path_index": int(jp.path_index[rows[pick[k]]]), "rows_evaluated": int(len(pick))}
    return {"work_rows": int(len(rows)), "joint_limit": joint_limit, "reach": reach, "manipulability": manip}
