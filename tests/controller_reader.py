"""Reading written programs the way the controller would, independently of camtool's readers and
simulator: RAPID ``MoveAbsJ`` through abb_driver's linkage (rax_3 = joint_3 + joint_2), robtargets
with their tooldata / wobjdata / confdata; JBI ``///RECTAN`` positions in the Motoman robot frame
(the URDF's ``base`` link) with ``///RCONF``. The robot is the vendored ROS-Industrial URDF in
Pinocchio. Only the *plan* (the trajectory CSV camtool writes) goes through camtool's model.

Used by tests/test_controller_truth.py and benchmarks/controller_truth.py.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

ROSI = Path(__file__).resolve().parents[1] / "camtool" / "robots" / "data" / "ros-industrial"
URDFS = {"irb2400": ROSI / "abb_irb2400_support" / "urdf" / "irb2400.urdf",
         "sia20": ROSI / "motoman_sia20d_support" / "urdf" / "sia20d.urdf"}
# the controllers' axis limits (deg), manufacturer specifications, controller axis order
LIMITS_DEG = {"irb2400": [(-180, 180), (-100, 110), (-60, 65), (-200, 200), (-120, 120), (-400, 400)],
              "sia20": [(-180, 180), (-110, 110), (-130, 130), (-180, 180), (-110, 110), (-180, 180), (-170, 170)]}
NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


class Urdf:
    """Forward kinematics of a vendored URDF (kinematics only)."""

    def __init__(self, path):
        self.model = pin.buildModelFromUrdf(str(path))
        self.data = self.model.createData()

    def frame(self, q_rad, name) -> np.ndarray:
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q_rad, float))
        M = self.data.oMf[self.model.getFrameId(name)]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = M.rotation, M.translation * 1000.0
        return T


def tool0(urdf: Urdf, robot: str, q_urdf) -> np.ndarray:
    """The controller's tool0 in the URDF's base_link (mm). SIA20D: link_t turned pi about z, as the
    xacro states it (the generated URDF rounds pi to 3.1416)."""
    if robot == "sia20":
        T = urdf.frame(q_urdf, "link_t")
        return T @ np.diag([-1.0, -1.0, 1.0, 1.0])
    return urdf.frame(q_urdf, "tool0")


# --- the ROS-I drivers' joint conventions (abb_driver abb_utils.cpp, motoman_driver CtrlGroup.c) ---
def urdf_from_rax(rax_deg) -> np.ndarray:
    j = np.radians(np.asarray(rax_deg, float))
    j[..., 2] -= j[..., 1]
    return j


def rax_from_urdf(j_rad) -> np.ndarray:
    r = np.degrees(np.asarray(j_rad, float)).copy()
    r[..., 2] += r[..., 1]
    return r


def motoman_from_urdf(j_rad) -> np.ndarray:
    """ROS S,L,E,U,R,B,T -> the controller's S,L,U,R,B,T,E (deg)."""
    d = np.degrees(np.asarray(j_rad, float))
    return np.concatenate([d[..., :2], d[..., 3:7], d[..., 2:3]], axis=-1)


def _pose(xyz, quat_wxyz) -> np.ndarray:
    T = np.eye(4)
    w, x, y, z = quat_wxyz
    T[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix()
    T[:3, 3] = xyz
    return T


def _nums(text) -> list[float]:
    return [float(v) for v in re.findall(NUM, text)]


@dataclass
class Target:
    kind: str                       # "J" (joint values given) or "L" / "C" (a pose given)
    line: int
    joints_deg: np.ndarray | None = None     # controller axis values as written (MoveAbsJ)
    pose: np.ndarray | None = None           # the TCP pose in the robot base frame (mm)
    conf: list[int] = field(default_factory=list)   # confdata / RCONF as written
    extra_deg: float | None = None           # INFORM Re (the E axis)


def read_rapid(mod: Path) -> list[Target]:
    """Targets of a RAPID module (and the modules it loads from the same folder, in order)."""
    text = mod.read_text(encoding="latin-1")
    pers = {m.group(2): m.group(3) for m in re.finditer(r"PERS\s+(tooldata|wobjdata)\s+(\w+)\s*:=(.*?);", text)}
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if s.startswith("MoveAbsJ"):
            rax = _nums(s[s.index("[[") + 2:s.index("]")])
            out.append(Target("J", n, joints_deg=np.array(rax)))
        elif s.startswith(("MoveL", "MoveC")):
            tool = re.search(r",\s*(\w+)\s*\\WObj:=(\w+)", s)
            tv = _nums(pers[tool.group(1)])          # [robhold, [[x,y,z],[q]], [mass, ...]]: robhold is no number
            tool_T = _pose(tv[0:3], tv[3:7])
            wv = _nums(pers[tool.group(2)].split('""', 1)[1])   # uframe then oframe
            W = _pose(wv[0:3], wv[3:7]) @ _pose(wv[7:10], wv[10:14])
            robts = re.findall(r"\[\[(" + NUM + r"),(" + NUM + r"),(" + NUM + r")\],\[([^\]]*)\],\[([^\]]*)\],\[[^\]]*\]\]", s)
            for i, rb in enumerate(robts):
                pos, q, cf = [float(v) for v in rb[:3]], _nums(rb[3]), [int(float(v)) for v in _nums(rb[4])]
                # the robtarget is the TCP (tooldata) in the work object
                out.append(Target("C" if s.startswith("MoveC") and i == 0 else s[4], n,
                                  pose=W @ _pose(pos, q), conf=cf))
                out[-1].tool = tool_T
        elif s.startswith("Load") or "CallByVar" in s:
            pass
    return out


def rapid_tool(mod: Path) -> np.ndarray:
    text = mod.read_text(encoding="latin-1")
    m = re.search(r"PERS\s+tooldata\s+\w+\s*:=(.*?);", text)
    tv = _nums(m.group(1))
    return _pose(tv[0:3], tv[3:7])


def read_jbi(path: Path) -> list[Target]:
    """Targets of a JBI job and the jobs it calls (CALL JOB, same folder), in run order."""
    lines = path.read_text(encoding="ascii").splitlines()
    pos, postype, rconf = {}, None, None
    out = []
    for n, line in enumerate(lines, 1):
        if line.startswith("///POSTYPE"):
            postype = line.split()[1]
        elif line.startswith("///RCONF"):
            rconf = [int(v) for v in line[9:].split(",")]
        elif re.match(r"^C\d{5}=", line):
            pos[line[:6]] = (postype, [float(v) for v in line[7:].split(",")], rconf)
        elif line.startswith("CALL JOB:"):
            out += read_jbi(path.parent / f"{line[9:].strip()}.JBI")
        elif line.startswith(("MOVJ", "MOVL", "MOVC")):
            ref = re.search(r"\bC\d{5}\b", line).group(0)
            kind, vals, rc = pos[ref]
            word = {"MOVJ": "J", "MOVL": "L", "MOVC": "C"}[line[:4]]
            if kind == "PULSE":
                raise ValueError(f"{path}:{n}: pulse position: its factors are the controller's, not in the job")
            R = Rotation.from_euler("xyz", vals[3:6], degrees=True).as_matrix()   # Rx, Ry, Rz fixed axes
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, vals[:3]
            out.append(Target(word, n, pose=T, conf=list(rc), extra_deg=vals[6] if len(vals) > 6 else None))
    return out


def _segment_distance(p, A, B):
    d = B - A
    L2 = np.einsum("ij,ij->i", d, d)
    t = np.clip(np.einsum("ij,ij->i", p[None] - A, d) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    X = A + t[:, None] * d
    dist = np.linalg.norm(X - p[None], axis=1)
    k = int(np.argmin(dist))
    return float(dist[k]), k, float(t[k])


@dataclass
class Truth:
    """Figures of one program read as the controller would."""

    targets: int
    max_pos_mm: float
    max_ori_deg: float
    conf_checked: int
    conf_mismatch: int
    switches: int
    switch_conf_mismatch: int
    beyond_limits: int
    max_extra_deg: float = 0.0


def plan_from_csv(csv: Path, robot_obj) -> tuple[np.ndarray, np.ndarray]:
    """(model joint values (N, dof) rad, planned TCP poses (N, 4, 4)) from camtool's trajectory CSV."""
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    q = np.radians(data[:, 1:])
    T = np.array([robot_obj.fk_tcp(x) for x in q])
    # The CSV samples the trajectory every 20 ms: a fast free move steps 30+ mm between rows, and the
    # chord of such a step is not the planned path. Rows are refined in joint space (the trajectory is
    # a joint-space curve) until the TCP steps <= 0.25 mm, so the polyline is the path to ~1e-3 mm.
    step = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)
    n = np.maximum(1, np.ceil(step / 0.25).astype(int))
    if n.max() == 1:
        return q, T
    qs, Ts = [q[:1]], [T[:1]]
    for i, m in enumerate(n):
        if m > 1:
            f = (np.arange(1, m) / m)[:, None]
            qi = q[i] + f * (q[i + 1] - q[i])
            qs.append(qi)
            Ts.append(np.array([robot_obj.fk_tcp(x) for x in qi]))
        qs.append(q[i + 1:i + 2])
        Ts.append(T[i + 1:i + 2])
    return np.concatenate(qs), np.concatenate(Ts)


def check_program(robot: str, targets: list[Target], q_plan: np.ndarray, T_plan: np.ndarray,
                  tool_T: np.ndarray) -> Truth:
    """Every target against the plan: TCP distance from the planned polyline, orientation against the
    planned TCP there, confdata / RCONF against the planned configuration's controller axes, limits."""
    urdf = Urdf(URDFS[robot])
    base = urdf.frame(np.zeros(urdf.model.nq), "base")  # the controller's robot frame in base_link
    P = T_plan[:, :3, 3]
    lim = np.array(LIMITS_DEG[robot], float)
    max_pos = max_ori = max_extra = 0.0
    conf_checked = conf_bad = switches = switch_bad = beyond = 0
    prev = None
    for tg in targets:
        if tg.kind == "J" and tg.joints_deg is not None:       # RAPID MoveAbsJ
            ctrl = tg.joints_deg
            T = tool0(urdf, robot, urdf_from_rax(ctrl)) @ tool_T
        else:
            T = (base @ tg.pose) if robot == "sia20" else tg.pose
            ctrl = None
        dist, k, t = _segment_distance(T[:3, 3], P[:-1], P[1:])
        j = k + int(t > 0.5)
        # the planned orientation there: slerp between the segment's ends
        Ra, Rb = Rotation.from_matrix(T_plan[k, :3, :3]), Rotation.from_matrix(T_plan[k + 1, :3, :3])
        R_here = (Ra * Rotation.from_rotvec(t * (Ra.inv() * Rb).as_rotvec())).as_matrix()
        ori = math.degrees(Rotation.from_matrix(R_here.T @ T[:3, :3]).magnitude())
        max_pos, max_ori = max(max_pos, dist), max(max_ori, ori)
        planned_ctrl = rax_from_urdf(q_plan[j]) if robot == "irb2400" else motoman_from_urdf(q_plan[j])
        ref = ctrl if ctrl is not None else planned_ctrl
        beyond += int(np.any(ref < lim[:, 0] - 1e-6) or np.any(ref > lim[:, 1] + 1e-6))
        if tg.conf:
            conf_checked += 1
            near_edge = False
            if robot == "irb2400":
                want = [math.floor(planned_ctrl[a] / 90.0) for a in (0, 3, 5)]
                near_edge = any(abs(planned_ctrl[a] / 90.0 - round(planned_ctrl[a] / 90.0)) < 0.02 for a in (0, 3, 5))
                ok = tg.conf[:3] == want and (tg.conf[3] % 2 == 1) == (planned_ctrl[4] < 0)
            else:   # RCONF: flip (B < 0), ..., R >= 180, T >= 180, S >= 180
                c = planned_ctrl
                ok = tg.conf[0] == int(c[4] < 0) and tg.conf[3:6] == [int(abs(c[3]) >= 180), int(abs(c[5]) >= 180),
                                                                         int(abs(c[0]) >= 180)]
                e_here = (1 - t) * np.degrees(q_plan[k, 2]) + t * np.degrees(q_plan[k + 1, 2])   # the E axis
                max_extra = max(max_extra, abs(tg.extra_deg - e_here)) if tg.extra_deg is not None else max_extra
            conf_bad += int(not ok and not near_edge)
        if prev is not None and (prev.kind == "J") != (tg.kind == "J") and robot == "irb2400":
            switches += 1
            jt, ct = (prev, tg) if prev.kind == "J" else (tg, prev)
            quad = [math.floor(jt.joints_deg[a] / 90.0) for a in (0, 3, 5)]
            edge = any(abs(jt.joints_deg[a] / 90.0 - round(jt.joints_deg[a] / 90.0)) < 0.05 for a in (0, 3, 5))
            switch_bad += int(ct.conf[:3] != quad and not edge)
        prev = tg
    return Truth(len(targets), max_pos, max_ori, conf_checked, conf_bad, switches, switch_bad, beyond, max_extra)
