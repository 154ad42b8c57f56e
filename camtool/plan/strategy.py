"""The planning strategy of the main seed (Sun et al. 2023, section 3.2) and its
baseline.

``method="seed"`` (default), step for step:

1. The path is split into *runs* (lead-in, work and lead-out poses of one
   segment: the tool is on the surface) and *connectors* (approach,
   self-motion and depart zones between runs).
2. Each run is solved pose by pose with CWLN, warm-started from the previous
   pose.
3. A joint step above the jump threshold (50 deg; the track has its own mm
   threshold) is a singularity: gradient-projection self-motion first moves
   the new solution towards the previous one without moving the tool.
4. If the jump is still there, reverse planning draws ``reverse_samples``
   IK solutions of the failing pose (seeded RNG), plans backwards to the run's
   first pose with steps 2-3, and splices in the first that makes it without a
   jump. The candidates come from the analytic families (``ik_seeds``, see
   ``AnalyticSeeds``) when the robot has them, else from random CWLN starts. The jump then falls into the connector before the run,
   where the arm reconfigures off the surface.
5. If all fail, the pose is marked singular, the self-motion solution closest
   to the previous pose is kept, and a retract-reorient-return move is
   inserted: a Cartesian lift of the tool along the surface normal (all
   joints), the reconfiguration at that height, and a Cartesian descent
   (``connectors.py``), for robots with and without a track.

``method="general"`` is CWLN alone, as the paper's baseline: jumps stay where
they occur.

Connector poses are solved after the runs on both sides are fixed, with
null-space motion pulling each towards the blend of the two runs' end
configurations, so the reconfiguration is spread over the zone.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from itertools import islice, product

import numpy as np

from ..errors import BadInput, PlanInfeasible
from ..robots.ik_common import limit_equivalents
from ..robots.ik_srs import track_shift
from ..robots.model import Robot
from ..settings import PlannerSettings
from ..path.toolpath import ZONE_CODE, ZONES, Path, run_bounds
from ..trajectory import JointPath
from .connectors import cartesian_lift
from .cwln import CwlnSolver, IkResult, IkSettings
from .kernel import DhKernel, load_compiled

RESTARTS_WHEN_LOST = 20
RETRACT_LIFT_STEPS = 5  # poses of each Cartesian lift / descent of a retract


class AnalyticSeeds:
    """Exact IK solutions of a TCP pose from a robot's closed-form families.

    SRS arms (``ik_srs``: sia20, seed8's 7R arm behind its track): each draw
    takes an arm angle, and a value for every joint in front of the arm (the
    track, inside ``lo``..``hi``), from the RNG and returns all 8 families
    inside the limits. 6R spherical-wrist arms (``ik_spherical_wrist``): all
    branches and their 2*pi-equivalents inside the limits, in one draw. With
    free tool spin, each draw also turns the target about tool z by a random
    angle. ``for_robot`` returns None when neither applies.
    """

    DRAW_TRIES = 8  # (track, arm angle) pairs tried per draw before the pose counts as out of analytic reach

    def __init__(self, robot: Robot, kind: str, ik, lo: np.ndarray, hi: np.ndarray, free_spin: bool):
        self.robot, self.kind, self.ik, self.free_spin = robot, kind, ik, free_spin
        self.n_pre = robot.dof - 7 if kind == "srs" else 0
        self.lo, self.hi = np.asarray(lo, float), np.asarray(hi, float)
        self.tool_inv = np.linalg.inv(robot.tool_T_mm)
        self.mid = 0.5 * (robot.limits.lower + robot.limits.upper)
        self.varies = kind == "srs" or free_spin  # whether a second draw can give new solutions
        self.shift = track_shift(robot, ik) if self.n_pre == 1 and robot.prismatic[0] else None

    @staticmethod
    def for_robot(robot: Robot, lo, hi, free_spin: bool = False) -> "AnalyticSeeds | None":
        """The analytic families of ``robot`` (SRS or spherical wrist), or None if it has neither."""
        from ..robots.ik_spherical_wrist import SphericalWristIK
        from ..robots.ik_srs import SrsIK

        if robot.dof >= 7:
            n_pre = robot.dof - 7
            try:
                return AnalyticSeeds(robot, "srs", SrsIK(robot, 0.5 * (np.asarray(lo) + hi)[:n_pre]), lo, hi,
                                     free_spin)
            except BadInput:
                return None
        try:
            return AnalyticSeeds(robot, "spherical_wrist", SphericalWristIK(robot), lo, hi, free_spin)
        except BadInput:
            return None

    def _flange(self, T_tcp, rng) -> np.ndarray:
        T = np.asarray(T_tcp, float)
        if self.free_spin:
            a = rng.uniform(-np.pi, np.pi)
            c, s = np.cos(a), np.sin(a)
            T = T @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        return T @ self.tool_inv

    def draw(self, T_tcp: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
        """Full-robot q's of one draw (inside the limits); [] if DRAW_TRIES draws give none."""
        from ..robots.ik_srs import SrsIK

        L = self.robot.limits
        for _ in range(self.DRAW_TRIES):
            T = self._flange(T_tcp, rng)
            out = []
            if self.kind == "srs":
                n = self.n_pre
                fixed = self.lo[:n] + (self.hi[:n] - self.lo[:n]) * rng.random(n)
                psi = rng.uniform(-np.pi, np.pi)
                try:
                    if self.shift is not None:  # the track moves the arm: move the target instead
                        T = T.copy()
                        T[:3, 3] -= (fixed[0] - self.ik.fixed[0]) * self.shift
                        sols = self.ik.solve(T, psi)
                    else:
                        sols = (SrsIK(self.robot, fixed) if n else self.ik).solve(T, psi)
                except PlanInfeasible:
                    continue
                for sol in sols:
                    eq = limit_equivalents(sol.q, L.lower[n:], L.upper[n:], np.ones(7, bool))
                    if eq is not None:  # the 2*pi-equivalent nearest mid-range
                        q = [min(v, key=lambda x, m=m: abs(x - m)) for v, m in zip(eq, self.mid[n:])]
                        out.append(np.concatenate([fixed, q]))
            else:
                for sol in self.ik.solve(T):
                    eq = limit_equivalents(sol.q, L.lower, L.upper, ~self.robot.prismatic)
                    if eq is not None:  # inside the controller's axis limits too (coupled J3)
                        out += [q for q in map(np.array, islice(product(*eq), 16)) if self.robot.within_limits(q)]
            if out or not self.varies:
                return out
        return []

    def stream(self, T_tcp: np.ndarray, rng: np.random.Generator):
        """Analytic q's of a pose, draw after draw; ends when a draw finds none (or cannot vary)."""
        while True:
            qs = self.draw(T_tcp, rng)
            yield from qs
            if not qs or not self.varies:
                return


def split_runs(path: Path) -> list[tuple[int, int]]:
    """Inclusive (first, last) index spans of runs (``toolpath.run_bounds``)."""
    _surface, start, end = run_bounds(path.zone, path.segment)
    return [(int(a), int(b)) for a, b in zip(np.flatnonzero(start), np.flatnonzero(end))]


class Planner:
    """Plans one Path for one robot; holds the per-pose arrays while it works."""

    def __init__(self, path: Path, robot: Robot, st: PlannerSettings, world=None):
        ik = ik_settings(st)
        self.world = world if world is not None and world.pairs else None
        self._world_on = True   # off while connector poses are planned: the lift stage re-routes those
        q_home = None if st.q_home is None else np.asarray(st.q_home, float)
        self.path, self.robot, self.st = path, robot, st
        self.solver = CwlnSolver(robot, ik, free_spin=path.free_spin)
        thr = np.where(robot.prismatic, st.jump_threshold_mm, st.jump_threshold_rad)
        self.kernel = DhKernel.build(robot, ik, path.free_spin, thr)
        base_inv = np.linalg.inv(robot.base_T_mm)
        self.targets = np.einsum("ij,njk->nik", base_inv, path.poses_mm)
        n, dof = len(path), robot.dof
        self.q = np.zeros((n, dof))
        self.pos_err = np.full(n, np.inf)
        self.ori_err = np.full(n, np.inf)
        self.reached = np.zeros(n, bool)
        self.reverse = np.zeros(n, bool)
        self.singular = np.zeros(n, bool)
        self.rng = np.random.default_rng(st.seed)
        self.thr = np.where(robot.prismatic, st.jump_threshold_mm, st.jump_threshold_rad)
        self.q_home = q_home
        self.coupled = robot.conventions.coupled
        self.seeds = None
        if st.ik_seeds != "random":
            buf = self.solver.buffer
            self.seeds = AnalyticSeeds.for_robot(robot, self.solver.lo + buf, self.solver.hi - buf, path.free_spin)
            if self.seeds is None and st.ik_seeds == "analytic":
                raise BadInput(f"planner.ik_seeds = 'analytic': {robot.name} has no closed-form IK families "
                               "(SRS arm or 6R spherical wrist); use 'auto' or 'random'")
        self.events = {"reverse_plans": [], "retracts": [], "gradient_projections": 0,
                       "start_configuration": None, "ik_seeds": "analytic" if self.seeds else "random",
                       "start_margin": None, "start_seconds": 0.0, "reverse_plan_seconds": 0.0}

    # -- helpers ---------------------------------------------------------
    def is_jump(self, qa, qb) -> bool:
        return bool(np.any(np.abs(qb - qa) > self.thr))

    def keep(self, k, res):
        self.q[k] = res.q
        self.pos_err[k] = res.position_error_mm
        self.ori_err[k] = res.orientation_error_rad
        self.reached[k] = res.converged

    def ik(self, k, q0, max_iterations=None) -> IkResult:
        """CWLN for pose k from q0: the compiled kernel when the robot has one.

        CWLN clamps the joint box; on a robot whose controller couples axes (the IRB2400's
        axis 3 = j2 + j3) a solution beyond a coupled axis' limits is not reached: the
        strategy then looks for another configuration, as for any pose it loses. So is a
        solution that brings a body into the cell or into the robot itself (``world``).
        """
        if self.kernel is None:
            res = self.solver.solve(self.targets[k], q0, max_iterations)
        else:
            res = IkResult(*self.kernel.solve(self.targets[k], q0, max_iterations))
        return self._screened(res)

    def gp(self, k, q, q_ref, iterations=200) -> IkResult:
        """Gradient-projection self-motion at pose k from q towards q_ref (kernel when available)."""
        if self.kernel is None:
            res = self.solver.self_motion(self.targets[k], q, q_ref, iterations)
        else:
            res = IkResult(*self.kernel.self_motion(self.targets[k], q, q_ref, iterations))
        return self._screened(res)

    def _screened(self, res: IkResult) -> IkResult:
        """``res``, not converged when it is beyond a coupled controller axis or in collision (``ik``)."""
        if self.coupled and res.converged and not self.robot.conventions.within_limits(res.q):
            return replace(res, converged=False)
        if self.world is not None and self._world_on and res.converged and not self.world.valid(res.q):
            return replace(res, converged=False)   # a link or the tool in the cell or in the robot itself
        return res

    def random_q(self) -> np.ndarray:
        lo, hi = self.solver.lo + self.solver.buffer, self.solver.hi - self.solver.buffer
        return lo + (hi - lo) * self.rng.random(self.robot.dof)

    def step(self, k, q_prev):
        """Steps 2-3 for pose k from q_prev: CWLN, then GP if it jumps. None if not reached."""
        res = self.ik(k, q_prev)
        if not res.converged:
            return None
        if self.st.method == "seed" and self.is_jump(q_prev, res.q):
            gp = self.gp(k, res.q, q_prev)
            self.events["gradient_projections"] += 1
            if gp.converged and np.max(np.abs(gp.q - q_prev) / self.thr) < np.max(np.abs(res.q - q_prev) / self.thr):
                return gp
        return res

    def candidates(self, k, random_start=None):
        """IK solutions of pose k to start from, one per try (None: that try did not converge).

        Analytic family solutions first (each polished by one CWLN solve), then
        CWLN from random starts (``random_start()``, default ``random_q``).
        """
        if self.seeds is not None:
            for q0 in self.seeds.stream(self.targets[k], self.rng):
                res = self.ik(k, q0, max_iterations=200)
                yield res if res.converged else None
        random_start = random_start or self.random_q
        while True:
            res = self.ik(k, random_start(), max_iterations=200)
            yield res if res.converged else None

    def find_any(self, k, tries):
        """IK for pose k from ``tries`` candidates: the first converged solution, or None."""
        return next((r for r in islice(self.candidates(k), tries) if r is not None), None)

    # -- start ----------------------------------------------------------------
    def margin(self, q) -> float:
        """Smallest distance of q to a joint limit, as a share of that joint's range."""
        span = self.solver.hi - self.solver.lo
        return float(np.min(np.minimum(q - self.solver.lo, self.solver.hi - q) / span))

    def start_configuration(self, k) -> np.ndarray:
        """A start for pose k: the job's home, else the candidate IK solution with most limit margin."""
        t0 = time.perf_counter()
        try:
            if self.q_home is not None:
                res = self.ik(k, self.q_home, max_iterations=300)
                if res.converged:
                    self.events["start_configuration"] = "home"
                    self.events["start_margin"] = self.margin(res.q)
                    return res.q
            span = self.solver.hi - self.solver.lo
            mid = self.solver.lo + 0.5 * span

            def near_mid():  # random starts near mid-range give natural postures
                return np.clip(mid + 0.15 * span * self.rng.standard_normal(self.robot.dof),
                               self.solver.lo, self.solver.hi)
            best, best_margin = None, -np.inf
            for res in islice(self.candidates(k, near_mid), max(self.st.reverse_samples, 20)):
                if res is not None and self.margin(res.q) > best_margin:
                    best, best_margin = res.q, self.margin(res.q)
            self.events["start_configuration"] = "searched"
            self.events["start_margin"] = None if best is None else best_margin
            return best if best is not None else mid
        finally:
            self.events["start_seconds"] += time.perf_counter() - t0

    # -- runs --------------------------------------------------------------
    def plan_run(self, a, b, q_in):
        """Forward over run poses a..b (inclusive) from q_in."""
        self.run_entry_q = np.asarray(q_in, float)
        res = self.ik(a, q_in, max_iterations=300)
        if self.st.method == "seed" and res.converged and self.is_jump(q_in, res.q):
            gp = self.gp(a, res.q, q_in)
            res = gp if gp.converged else res
        if not res.converged:
            res = self.find_any(a, RESTARTS_WHEN_LOST) or res
        self.keep(a, res)
        k = a + 1
        while k <= b:
            q_prev = self.q[k - 1]
            if self.kernel is not None and self.reached[k - 1]:
                # fast path: compiled CWLN until the first pose that jumps or fails
                stop, qs, pe, oe = self.kernel.run(self.targets[k:b + 1], q_prev)
                if self.coupled and stop:   # up to the first pose beyond a coupled controller axis
                    inside = self.robot.conventions.within_limits(qs[:stop])
                    stop = int(np.argmin(inside)) if not inside.all() else stop
                if self.world is not None and self._world_on and stop:   # up to the first pose in collision
                    clear = self.world.valid_many(qs[:stop])
                    stop = int(np.argmin(clear)) if not clear.all() else stop
                for m in range(stop):
                    self.keep(k + m, IkResult(qs[m], pe[m], oe[m], True, 0))
                k += stop
                if k > b:
                    break
                q_prev = self.q[k - 1]
            self.handle(k, a, q_prev)
            k += 1

    def handle(self, k, a, q_prev):
        """Pose k from q_prev with the full strategy: steps 2-5, or unreachable."""
        res = self.step(k, q_prev)
        if res is None:
            tries = RESTARTS_WHEN_LOST if self.reached[k - 1] else 0
            res = self.find_any(k, tries)
            if res is None:  # unreachable: keep going from the last configuration
                self.keep(k, self.ik(k, q_prev))
                return
        if self.is_jump(q_prev, res.q) and self.st.method == "seed" and self.reached[k - 1]:
            if not self.reverse_plan(k, a):
                self.fallback(k, q_prev, res)
            return
        self.keep(k, res)

    def reverse_plan(self, k, a) -> bool:
        """Step 4 (timed): candidate IK solutions of pose k, planned backwards to a; splice the first that works."""
        t0 = time.perf_counter()
        try:
            return self._reverse_plan(k, a)
        finally:
            self.events["reverse_plan_seconds"] += time.perf_counter() - t0

    def reconfiguration_s(self, qa, qb) -> float:
        """The shortest time (s) a joint move qa -> qb can take at the joints' speed limits."""
        return float(np.max(np.abs(np.asarray(qb) - qa) / self.robot.limits.velocity))

    def _reverse_plan(self, k, a) -> bool:
        """Up to ``reverse_best_of`` successful backward plans; keep the cheapest connector into the run.

        Cost: the reconfiguration time from the run's entry configuration (the
        previous run's end) to the chain's first pose, at the speed limits,
        plus the chain's own joint travel in the same measure.
        """
        best, best_cost, successes, tried = None, np.inf, 0, 0
        for attempt, res in enumerate(islice(self.candidates(k), self.st.reverse_samples)):
            tried = attempt + 1
            if res is None:
                continue
            chain = [res]
            ok = True
            for m in range(k - 1, a - 1, -1):
                r = self.step(m, chain[-1].q)
                if r is None or self.is_jump(chain[-1].q, r.q):
                    ok = False
                    break
                chain.append(r)
            if not ok:
                continue
            successes += 1
            cost = self.reconfiguration_s(self.run_entry_q, chain[-1].q) + sum(
                self.reconfiguration_s(x.q, y.q) for x, y in zip(chain[:-1], chain[1:]))
            if cost < best_cost:
                best, best_cost, best_attempt = chain, cost, attempt + 1
            if successes >= self.st.reverse_best_of:
                break
        if best is None:
            return False
        for m, r in zip(range(k, a - 1, -1), best):
            self.keep(m, r)
            self.reverse[m] = True
        self.events["reverse_plans"].append({"index": int(k), "segment": int(self.path.segment[k]),
                                             "point": int(self.path.point[k]), "attempt": best_attempt,
                                             "candidates": successes, "tried": tried,
                                             "reconfiguration_s": round(best_cost, 4)})
        return True

    def fallback(self, k, q_prev, res):
        """Step 5: keep the self-motion solution closest to q_prev; mark k for a retract."""
        gp = self.gp(k, res.q, q_prev, iterations=400)
        best = gp if gp.converged and np.linalg.norm(gp.q - q_prev) < np.linalg.norm(res.q - q_prev) else res
        self.keep(k, best)
        self.singular[k] = True
        p = self.path.poses_mm[k][:3, 3]
        self.events["retracts"].append({"index": int(k), "segment": int(self.path.segment[k]),
                                        "point": int(self.path.point[k]),
                                        "xyz_mm": [round(float(x), 3) for x in p]})

    # -- connectors ------------------------------------------------------
    def plan_connector(self, idx, q_from, q_to):
        """Connector poses idx (in order) from q_from towards q_to, spreading the change.

        Not screened against the cell: the lift stage (``connectors.lift_connectors``) checks every
        connector against the part and the cell and routes it round what it would hit."""
        self._world_on = False
        try:
            self._plan_connector(idx, q_from, q_to)
        finally:
            self._world_on = True

    def _plan_connector(self, idx, q_from, q_to):
        prev = q_from
        m = len(idx)
        for i, k in enumerate(idx):
            ref = q_from + (q_to - q_from) * (i + 1) / (m + 1)
            res = self.ik(k, prev)
            if not res.converged:
                res = self.ik(k, ref, max_iterations=300)
            if not res.converged:
                res = self.find_any(k, RESTARTS_WHEN_LOST) or res
            if res.converged:
                gp = self.gp(k, res.q, ref, iterations=60)
                res = gp if gp.converged else res
            self.keep(k, res)
            prev = res.q

    def plan(self) -> JointPath:
        runs = split_runs(self.path)
        if not runs:
            raise BadInput("the path has no work poses to plan")
        q_in = self.start_configuration(runs[0][0])
        for a, b in runs:
            self.plan_run(a, b, q_in)
            q_in = self.q[b]
        # approach: backwards from the first run; depart: forward from the last
        first, last = runs[0][0], runs[-1][1]
        self.plan_connector(list(range(first - 1, -1, -1)), self.q[first], self.q[first])
        self.plan_connector(list(range(last + 1, len(self.path))), self.q[last], self.q[last])
        for (a0, b0), (a1, b1) in zip(runs[:-1], runs[1:]):
            self.plan_connector(list(range(b0 + 1, a1)), self.q[b0], self.q[a1])
        return self.joint_path()

    # -- output -------------------------------------------------------------
    def retract_poses(self, k) -> list[np.ndarray]:
        """The retract-reorient-return configurations inserted before pose k.

        A Cartesian lift along the surface normal from pose k-1 (every joint,
        the track included, by CWLN), then the lifted pose of k reached from
        above, then a Cartesian descent onto k (``connectors.cartesian_lift``):
        the reconfiguration happens off the part, for robots with or without a
        track. The lift is ``retract_mm``; where the robot cannot reach that
        high (a part at the edge of reach), 1/2 and then 1/4 of it: the highest
        lift that can be solved is taken, the least it needs to leave the part.
        """
        qa, qb = self.q[k - 1], self.q[k]
        best = None
        for height in (self.st.retract_mm, self.st.retract_mm / 2, self.st.retract_mm / 4):
            up = cartesian_lift(self.solver, self.targets[k - 1], qa, height, RETRACT_LIFT_STEPS)
            down = cartesian_lift(self.solver, self.targets[k], qb, height, RETRACT_LIFT_STEPS) if up is not None \
                else None
            if up is not None and down is not None:
                best = list(up) + list(down[::-1])
                break
        if best is None:
            p = self.path.poses_mm[k][:3, 3]
            raise PlanInfeasible(f"pose {k} ({self.path.segment_text(k)}) needs a reconfiguration, but the "
                                 f"tool cannot be lifted off the surface there (tried {self.st.retract_mm:g} mm and "
                                 f"less; at {[round(float(x), 1) for x in p]} mm): the part is at the edge of the "
                                 "robot's reach; move it closer (camtool place) or lower planner.retract_mm")
        return best

    def joint_path(self) -> JointPath:
        rows, rows_idx, rows_retract = [], [], []
        for k in range(len(self.path)):
            if self.singular[k] and k > 0:
                for qr in self.retract_poses(k):
                    rows.append(qr); rows_idx.append(-1); rows_retract.append(True)
            rows.append(self.q[k]); rows_idx.append(k); rows_retract.append(False)
        idx = np.array(rows_idx)
        q = np.array(rows)
        src = np.maximum(idx, 0)
        zone = np.where(idx >= 0, self.path.zone[src], ZONE_CODE["retract"])
        jump = np.zeros(len(q), bool)
        jump[1:] = np.any(np.abs(np.diff(q, axis=0)) > self.thr, axis=1)

        def spread(a, fill):
            out = a[src].copy()
            out[idx < 0] = fill
            return out

        return JointPath(
            q=q, path_index=idx, zone=zone.astype(self.path.zone.dtype),
            position_error_mm=spread(self.pos_err, 0.0), orientation_error_rad=spread(self.ori_err, 0.0),
            jump=jump, reverse_planned=spread(self.reverse, False), retract=np.array(rows_retract),
            singular=spread(self.singular, False), reached=spread(self.reached, True), events=self.events,
        )


def ik_settings(settings: PlannerSettings) -> IkSettings:
    """The CWLN solver's settings from the planner's (posture pull for the seed method only)."""
    return IkSettings(damping=settings.damping, orientation_weight_mm=settings.orientation_weight_mm,
                      position_tol_mm=settings.position_tol_mm, orientation_tol_rad=settings.orientation_tol_rad,
                      max_iterations=settings.max_iterations, clamp_buffer_rad=settings.clamp_buffer_rad,
                      clamp_buffer_mm=settings.clamp_buffer_mm, track_scale_mm=settings.track_scale_mm,
                      posture_gain=settings.posture_gain if settings.method == "seed" else 0.0)


def _explain_bend(entry: dict, q: np.ndarray, world, robot: Robot) -> None:
    """Where every configuration collides because the wrist bends the tool into the link before it, say how far
    the wrist bends there and how far this tool lets it (``collision.wrist_bend``), in the entry's reason."""
    if world is None or not entry.get("reason", "").startswith("every configuration tried collides"):
        return
    from ..collision.wrist_bend import WristBend

    bend = WristBend(world).why(q, robot.joint_names)
    if bend:
        entry["reason"] += f": {bend}"


def plan_path(path: Path, robot: Robot, settings: PlannerSettings, world=None) -> JointPath:
    """Plan joint values (rad / mm) for every pose of ``path``.

    ``world``: the job's ``CollisionWorld``; a configuration that brings a robot or tool body
    closer than its clearance to an obstacle, the floor or another link is not taken.
    Raises PlanInfeasible (with a report listing them) when poses cannot be reached.
    ``events['plan_seconds']`` is the planning's own wall time and ``events['plan_cpu_seconds']`` its CPU time
    (what other processes on its core do not lengthen): the compiled kernels are loaded before either.
    """
    if settings.method not in ("seed", "general"):
        raise BadInput(f"planner.method: {settings.method!r} does not plan raster paths; use 'seed' or 'general'")
    if settings.q_home is not None and len(settings.q_home) != robot.dof:
        raise BadInput(f"robot.home_deg: {robot.name} needs {robot.dof} values, found {len(settings.q_home)}")
    if robot.dh:   # the compiled kernel's robots
        load_compiled()
    t0, cpu0 = time.perf_counter(), time.process_time()
    jp = Planner(path, robot, settings, world).plan()
    jp = replace(jp, events={**jp.events, "plan_seconds": time.perf_counter() - t0,
                             "plan_cpu_seconds": time.process_time() - cpu0})
    missed = np.flatnonzero((jp.path_index >= 0) & ~jp.reached)
    if len(missed):
        k = jp.path_index[missed]
        unreachable = [{"index": int(i), "segment": int(path.segment[i]), "point": int(path.point[i]),
                        **({} if path.face is None else {"face": int(path.face[i])}),
                        "zone": ZONES[path.zone[i]],
                        "xyz_mm": [round(float(x), 3) for x in path.poses_mm[i][:3, 3]],
                        "position_error_mm": round(float(jp.position_error_mm[m]), 3)}
                       for i, m in zip(k, missed)]
        conv = robot.conventions
        for entry, m in zip(unreachable, missed):   # on the tool, but beyond a coupled controller axis
            beyond = conv.check_controller_limits(conv.controller_from_model(jp.q[m])) if conv.coupled else []
            if beyond and entry["position_error_mm"] < 0.01:
                entry["reason"] = beyond[0]
            elif world is not None and entry["position_error_mm"] < 0.01:
                hit = world.closest_pair_text(jp.q[m])   # on the tool, but every configuration tried collides
                if hit:
                    entry["reason"] = f"every configuration tried collides: {hit}"
        first = unreachable[0]
        _explain_bend(first, jp.q[missed[0]], world, robot)
        why = f"; there {first['reason']}" if "reason" in first else ""
        raise PlanInfeasible(
            f"{len(unreachable)} of {len(path)} path poses are out of reach of {robot.name} "
            f"(first: pose {first['index']}, {path.segment_text(first['index'])}, point {first['point']}, "
            f"at {first['xyz_mm']} mm{why}); see report.json",
            report={"unreachable": unreachable, "joint_path": jp})
    return jp
