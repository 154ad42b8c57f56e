"""Reading KUKA KRL and FANUC LS programs the way their controllers would, independently of
camtool's writers, readers and simulator (as tests/controller_reader.py does for RAPID and
INFORM). The robots are the vendored ROS-Industrial URDFs in Pinocchio, driven through the
drivers' conventions, written here from the driver sources:

- KUKA (kuka_rsi_hw_interface / kuka_eki_hw_interface): ROS joint_aN = AN in degrees,
  converted to radians, nothing else; the URDF's ``tool0`` is the controller's $TOOL with
  $NULLFRAME (kuka_kr16_support's macro; KUKA's kroshu/kuka_robot_descriptions README) and
  ``base_link`` its $ROBROOT. A PTP's E6AXIS goes through the URDF; a LIN / CIRC's E6POS is
  the TCP in $BASE, with KUKA's A, B, C = rotations about z, the new y, the newest x.
- FANUC (fanuc_driver fanuc_utils.cpp, J23_factor = 1 in the M-20iA's launch file; the
  Karel state server sends CURJPOS in degrees): ROS joint_3 = J3 + J2 of the pendant; the
  URDF's ``tool0`` is the all-zeros tool frame, UTOOL's X, Y, Z, W, P, R on it (W, P, R about
  the fixed x, y, z axes).

Only the *plan* (the trajectory CSV camtool writes) goes through camtool's model.
Used by tests/test_controller_truth_kf.py and benchmarks/controller_truth.py.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from controller_reader import Urdf, _segment_distance

ROSI = Path(__file__).resolve().parents[1] / "camtool" / "robots" / "data" / "ros-industrial"
URDFS = {"kr16": ROSI / "kuka_kr16_support" / "urdf" / "kr16_2.urdf",
         "m20ia": ROSI / "fanuc_m20ia_support" / "urdf" / "m20ia.urdf"}
# the controllers' axis limits (deg), as the ROS-I packages give them from the manufacturers' data:
# KUKA A1..A6; FANUC J1..J6 with J3 the pendant's (from the horizontal)
LIMITS_DEG = {"kr16": [(-185, 185), (-155, 35), (-130, 154), (-350, 350), (-130, 130), (-350, 350)],
              "m20ia": [(-170, 170), (-100, 160), (-185, 273.12), (-200, 200), (-140, 140), (-270, 270)]}
NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)"


def urdf_limits_deg(robot: str) -> np.ndarray:
    """The URDF's own joint limits (deg), (6, 2): FANUC's serial joint_3 keeps the manual's range too."""
    m = pin.buildModelFromUrdf(str(URDFS[robot]))
    return np.degrees(np.stack([m.lowerPositionLimit, m.upperPositionLimit], axis=1))


# --- the drivers' joint conventions ------------------------------------------------------------
def urdf_from_kuka(a_deg) -> np.ndarray:
    """kuka_rsi_hw_interface: joint_aN = AN, degrees to radians."""
    return np.radians(np.asarray(a_deg, float))


def urdf_from_fanuc(j_deg) -> np.ndarray:
    """fanuc_driver (J23_factor = 1): joint_3 = J3 + J2 (the pendant's J3 is from the horizontal)."""
    j = np.radians(np.asarray(j_deg, float)).copy()
    j[..., 2] += j[..., 1]
    return j


def fanuc_from_urdf(q) -> np.ndarray:
    d = np.degrees(np.asarray(q, float)).copy()
    d[..., 2] -= d[..., 1]
    return d


# --- frames ------------------------------------------------------------------------------------
def kuka_frame(fields: dict) -> np.ndarray:
    """A KRL frame: X, Y, Z (mm) and A, B, C: R = Rz(A) Ry(B) Rx(C)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("ZYX", [fields["A"], fields["B"], fields["C"]], degrees=True).as_matrix()
    T[:3, 3] = [fields["X"], fields["Y"], fields["Z"]]
    return T


def fanuc_frame(fields: dict) -> np.ndarray:
    """A FANUC position's X, Y, Z (mm), W, P, R: R = Rz(R) Ry(P) Rx(W)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [fields["W"], fields["P"], fields["R"]], degrees=True).as_matrix()
    T[:3, 3] = [fields["X"], fields["Y"], fields["Z"]]
    return T


@dataclass
class Target:
    kind: str                      # "J" (joint values given) or "L" / "C" (a TCP pose given or reached)
    where: str
    joints_deg: np.ndarray | None = None   # controller axis values as written (E6AXIS, LS joint position)
    pose: np.ndarray | None = None         # the TCP in base_link (mm)
    extra: dict = field(default_factory=dict)


def _fields(body: str) -> dict:
    return {m.group(1).upper(): float(m.group(2)) for m in re.finditer(rf"([A-Za-z]\w*)\s+({NUM})", body)}


# --- KRL ---------------------------------------------------------------------------------------
def read_krl(src: Path) -> tuple[list[Target], np.ndarray]:
    """Targets of a .src (with its .dat, and the modules it calls) and the $TOOL (4 x 4, in tool0)."""
    out: list[Target] = []
    tool = [None]

    def module(p: Path):
        dat = {m.group(2).upper(): (m.group(1).upper(), _fields(m.group(3)))
               for m in re.finditer(r"DECL\s+(E6AXIS|E6POS)\s+(\w+)\s*=\s*\{([^}]*)\}", p.with_suffix(".dat").read_text())}
        base = None
        for n, line in enumerate(p.read_text().splitlines(), 1):
            s = line.strip()
            if s.startswith(";") or not s:
                continue
            if (m := re.match(r"\$BASE\s*=\s*\{([^}]*)\}", s)):
                base = kuka_frame(_fields(m.group(1)))
            elif (m := re.match(r"\$TOOL\s*=\s*\{([^}]*)\}", s)):
                tool[0] = kuka_frame(_fields(m.group(1)))
            elif (m := re.match(r"(PTP|LIN|CIRC)\s+(\w+)(?:\s*,\s*(\w+))?", s, re.I)):
                word = m.group(1).upper()
                if word == "PTP":
                    f = dat[m.group(2).upper()][1]
                    out.append(Target("J", f"{p.name}:{n}", joints_deg=np.array([f[f"A{i}"] for i in range(1, 7)])))
                else:
                    names = [m.group(2)] + ([m.group(3)] if m.group(3) else [])
                    for k, nm in enumerate(names):
                        out.append(Target("C" if word == "CIRC" and k == 0 else "L", f"{p.name}:{n}",
                                          pose=base @ kuka_frame(dat[nm.upper()][1])))
            elif (m := re.match(r"(\w+)\s*\(\s*\)$", s)) and (p.parent / f"{m.group(1)}.src").exists():
                module(p.parent / f"{m.group(1)}.src")
    module(Path(src))
    return out, tool[0]


# --- LS ----------------------------------------------------------------------------------------
def read_ls(path: Path) -> tuple[list[Target], np.ndarray]:
    """Targets of an LS program (and the programs it calls) and the UTOOL it sets (4 x 4, in tool0)."""
    out: list[Target] = []
    tool = [np.eye(4)]

    def program(p: Path):
        text = p.read_text()
        mn, pos = text.split("/MN", 1)[1].split("/POS", 1)
        positions = {}
        for m in re.finditer(r"P\[(\d+)\]\{(.*?)\};", pos.split("/END")[0], re.S):
            positions[int(m.group(1))] = {k: float(v) for k, v in re.findall(rf"\b(J\d|X|Y|Z|W|P|R)\s*=\s*({NUM})", m.group(2))}
        pr = {}
        lines = mn.strip().splitlines()
        for i, line in enumerate(lines):
            s = line.split(":", 1)[1].strip() if ":" in line else line.strip()
            if (m := re.match(r"PR\[(\d+)\]\s*=\s*P\[(\d+)\]", s)):
                pr[int(m.group(1))] = positions[int(m.group(2))]
            elif (m := re.match(r"UTOOL\[(\d+)\]\s*=\s*PR\[(\d+)\]", s)):
                tool[0] = fanuc_frame(pr[int(m.group(2))])
            elif (m := re.match(r"([JLC])\s+P\[(\d+)\]", s)):
                nums = [int(m.group(2))]
                if m.group(1) == "C":
                    nums.append(int(re.search(r"P\[(\d+)\]", lines[i + 1]).group(1)))
                for k, num in enumerate(nums):
                    f = positions[num]
                    out.append(Target("C" if m.group(1) == "C" and k == 0 else m.group(1), f"{p.name}:{line.split(':')[0].strip()}",
                                      joints_deg=np.array([f[f"J{i}"] for i in range(1, 7)])))
            elif (m := re.match(r"CALL\s+(\w+)", s)):
                program(p.parent / f"{m.group(1)}.LS")
    program(Path(path))
    return out, tool[0]


# --- the check ---------------------------------------------------------------------------------
@dataclass
class Truth:
    """Figures of one program read as its controller would."""

    targets: int
    max_pos_mm: float
    max_ori_deg: float
    switches: int
    switch_mismatch: int
    beyond_limits: int
    beyond_serial: int = 0
    max_switch_joint_deg: float = 0.0


def _ik(urdf: Urdf, T_tool0: np.ndarray, q0: np.ndarray, iters: int = 200) -> tuple[np.ndarray, float]:
    """URDF joints reaching a tool0 pose (mm) from q0 by damped least squares; (q, position error mm)."""
    model, data = urdf.model, urdf.data
    fid = model.getFrameId("tool0")
    target = pin.SE3(T_tool0[:3, :3], T_tool0[:3, 3] / 1000.0)
    q = np.array(q0, float)
    for _ in range(iters):
        pin.framesForwardKinematics(model, data, q)
        err = pin.log6(data.oMf[fid].actInv(target)).vector
        if np.linalg.norm(err) < 1e-10:
            break
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
        dq = J.T @ np.linalg.solve(J @ J.T + 1e-8 * np.eye(6), err)
        q = q + dq / max(1.0, float(np.max(np.abs(dq))) / 0.1)   # short steps: stay on the branch
    pin.framesForwardKinematics(model, data, q)
    return q, float(np.linalg.norm(data.oMf[fid].translation * 1000.0 - T_tool0[:3, 3]))


def check_program(robot: str, targets: list[Target], q_plan: np.ndarray, T_plan: np.ndarray,
                  tool_T: np.ndarray) -> Truth:
    """Every target against the plan: the TCP's distance from the planned polyline and its
    orientation against the planned TCP there; every axis value against the controller's limits
    (FANUC: the pendant's J3, and its serial joint_3 against the URDF's range too); where a joint
    move meets a Cartesian one, the Cartesian target solved through the URDF from the joint
    target's joints must stay on that branch (no other configuration)."""
    urdf = Urdf(URDFS[robot])
    to_urdf = urdf_from_kuka if robot == "kr16" else urdf_from_fanuc
    lim = np.array(LIMITS_DEG[robot], float)
    ulim = urdf_limits_deg(robot)
    P = T_plan[:, :3, 3]
    max_pos = max_ori = max_sw = 0.0
    switches = sw_bad = beyond = beyond_serial = 0
    prev = None
    for tg in targets:
        if tg.joints_deg is not None:
            qu = to_urdf(tg.joints_deg)
            T = urdf.frame(qu, "tool0") @ tool_T
            ctrl = tg.joints_deg
        else:
            T = tg.pose
            qu, ctrl = None, None
        dist, k, t = _segment_distance(T[:3, 3], P[:-1], P[1:])
        Ra, Rb = Rotation.from_matrix(T_plan[k, :3, :3]), Rotation.from_matrix(T_plan[k + 1, :3, :3])
        R_here = (Ra * Rotation.from_rotvec(t * (Ra.inv() * Rb).as_rotvec())).as_matrix()
        max_pos = max(max_pos, dist)
        max_ori = max(max_ori, math.degrees(Rotation.from_matrix(R_here.T @ T[:3, :3]).magnitude()))
        if ctrl is None and prev is not None and prev[1] is not None:
            # a Cartesian target: the controller solves it from where the robot is (the move before)
            qu, err = _ik(urdf, T @ np.linalg.inv(tool_T), prev[1])
            ctrl = np.degrees(qu) if robot == "kr16" else fanuc_from_urdf(qu)
        if ctrl is not None:
            beyond += int(np.any(ctrl < lim[:, 0] - 1e-6) or np.any(ctrl > lim[:, 1] + 1e-6))
            qd = np.degrees(qu)
            beyond_serial += int(np.any(qd < ulim[:, 0] - 1e-3) or np.any(qd > ulim[:, 1] + 1e-3))
        if prev is not None and (prev[0].kind == "J") != (tg.kind == "J"):
            switches += 1
            if prev[1] is not None and qu is not None:
                jump = float(np.max(np.abs(np.degrees(qu - prev[1]))))
                max_sw = max(max_sw, jump)
                # a configuration change turns a joint by tens of degrees between neighbouring targets
                sw_bad += int(jump > 45.0)
        prev = (tg, qu)
    return Truth(len(targets), max_pos, max_ori, switches, sw_bad, beyond, beyond_serial, max_sw)
