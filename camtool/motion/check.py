"""The independent motion check: sample the joint-linear motion at <= 4 ms and
measure it against the part (docs/motion-check.md).

Nothing here comes from the planner or the timing stage: the inputs are
waypoint times, joint values and zones; the robot's DH table gives the
geometry (``fk_batch``); the part is a ``PartGeometry``.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import BadInput
from ..path.toolpath import SURFACE_CODES, WORK, ZONE_CODE, ZONES
from .fk_batch import BatchFK
from .geometry import PartGeometry

NON_WORK = tuple(ZONE_CODE[z] for z in ("self_motion", "approach", "depart", "retract"))
LINK_ROLES = ("wrist", "forearm", "upper_arm")
MIN_HALF_PIECE_MM = 0.5  # capsule axes are sampled at <= max(radius / 2, 1 mm)


@dataclass(frozen=True)
class MotionCheckSettings:
    """What the check samples and what it accepts (lengths in mm)."""

    dt_s: float = 0.004                  # largest sampling step of the joint-linear motion
    penetration_tol_mm: float = 0.1      # deeper than this behind the surface fails
    clearance_mm: float = 5.0            # free clearance required of tool and links off work
    path_tol_mm: float = 0.1             # |TCP off the surface| allowed on work
    tool_radius_mm: float = 25.0         # tool capsule, flange to TCP
    link_radius_mm: float = 60.0         # link capsules
    links: int = 3                       # links checked, counted back from the flange
    tool_contact_exempt_mm: float = 30.0  # length of the chain before the TCP left out of the bodies
    contact_allowance_mm: float = 2.0    # TCP clearance ignores samples this close to a surface waypoint
    on_surface_tol_mm: float = 0.5       # a waypoint whose TCP is this close to the surface touches it
    chunk_samples: int = 50_000          # samples processed at a time (bounded memory)
    max_findings_per_kind: int = 10      # lines per body and kind before a summary line
    scan_band_mm: float = 0.0            # a scanned mesh's noise band: the TCP's tolerances on the part grow by it

    @property
    def tcp_surface_tol_mm(self) -> float:
        """How deep the TCP may go behind the part on work, leads and within the contact allowance of a waypoint
        touching it (a scan's noise band on top)."""
        return self.penetration_tol_mm + self.scan_band_mm

    @property
    def work_path_tol_mm(self) -> float:
        """How far the TCP may be off the part on work (a scan's noise band on top)."""
        return self.path_tol_mm + self.scan_band_mm

    def __post_init__(self):
        positive = ("dt_s", "chunk_samples")
        for name, value in asdict(self).items():
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value)
            if not ok or value < 0 or (name in positive and value <= 0):
                need = "> 0" if name in positive else ">= 0"
                raise BadInput(f"motion check: {name}: expected a number {need}, found {value!r}")


@dataclass(frozen=True)
class Place:
    """Where a figure was found: sample time, zone, the waypoint moved towards, and the body."""

    t_s: float
    zone: str
    waypoint: int
    at_waypoint: bool
    index: int | None        # the caller's index (path index, segment) of that waypoint
    index_label: str
    index_relation: str      # "at", "before" or "after" that index
    body: str

    def text(self) -> str:
        where = f"t = {self.t_s:.3f} s in {self.zone}"
        if self.index is not None:
            where += f" {self.index_relation} {self.index_label} {self.index}"
        return where

    def to_dict(self) -> dict:
        return {"t_s": round(self.t_s, 6), "zone": self.zone, "waypoint": self.waypoint,
                "index": self.index, "index_label": self.index_label, "relation": self.index_relation,
                "body": self.body}


@dataclass(frozen=True)
class MotionReport:
    """Figures of one motion check; ``ok`` is False when a finding fails it."""

    ok: bool
    samples: int
    dt_s: float
    duration_s: float
    max_penetration_mm: float
    max_penetration_at: Place | None
    min_clearance_mm: float | None       # None: every off-work body stays beyond the part's horizon
    min_clearance_at: Place | None
    tcp_min_clearance_mm: float | None
    tcp_min_clearance_at: Place | None
    work_deviation_mm: float | None      # None: no work samples
    work_deviation_at: Place | None
    work_beyond_edge_mm: float | None    # information: farthest work sample beyond the part's edge
    work_beyond_edge_at: Place | None
    max_joint_step_deg_per_mm: float | None
    max_joint_step_at: Place | None      # body = the joint
    max_track_step_mm_per_mm: float | None
    max_track_step_at: Place | None
    findings: tuple[str, ...]
    bodies: tuple[dict, ...]
    part: dict
    settings: MotionCheckSettings
    check_seconds: float = 0.0
    horizon_mm: float = 0.0
    cell_pairs: tuple[dict, ...] = ()   # per pair of bodies (link x obstacle, link x link): min distance, where
    cell: dict | None = None            # the collision world's bodies and the cell pass's figures
    by_index: tuple[dict, ...] = ()     # per caller's index (e.g. segment): its samples' worst figures
    # every failing sample against the part, as (kind, body, waypoint before, waypoint after) once each (the two
    # equal for a sample at a waypoint): where a partial plan leaves poses out (not in report.json: ``to_dict``)
    failing_intervals: tuple[tuple[str, str, int, int], ...] = ()

    def to_dict(self) -> dict:
        d = {}
        for k, v in self.__dict__.items():
            if k == "failing_intervals":
                continue
            if isinstance(v, Place):
                v = v.to_dict()
            elif isinstance(v, MotionCheckSettings):
                v = asdict(v)
            elif isinstance(v, tuple):
                v = list(v)
            elif isinstance(v, float):
                v = round(v, 6)
            d[k] = v
        return d


@dataclass(frozen=True)
class _Body:
    name: str
    kind: str          # "tool" or "link"
    radius: float
    start: int         # chain point index: 0..dof-1 joint origins, dof = flange, dof + 1 = TCP
    end: int
    exempt_before: float  # chain length between this body's end and the TCP


class _Samples:
    """The joint-linear sampling: per sample its interval, fraction, time, zone and waypoint."""

    def __init__(self, t_s, zone, dt_s):
        M = len(t_s)
        if M == 1:
            self.seg = np.zeros(1, np.int64)
            self.frac = np.zeros(1)
            self.t = t_s.copy()
            self.wp = np.zeros(1, np.int64)
            self.at_wp = np.ones(1, bool)
            self.zone = zone.copy()
            return
        h = np.diff(t_s)
        n = np.maximum(1, np.ceil(h / dt_s - 1e-9).astype(np.int64))
        seg = np.repeat(np.arange(M - 1), n)
        k = np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)
        self.seg = np.append(seg, M - 2)
        self.frac = np.append(k / n[seg], 1.0)
        self.t = t_s[self.seg] + self.frac * h[self.seg]
        self.t[-1] = t_s[-1]
        self.at_wp = np.append(k == 0, True)
        self.wp = np.where(self.at_wp, self.seg, self.seg + 1)
        self.wp[-1] = M - 1
        z0, z1 = zone[:-1], zone[1:]
        seg_zone = np.where((z1 == WORK) & (z0 != WORK), z0, z1)
        self.zone = np.where(self.at_wp, zone[self.wp], seg_zone[self.seg])

    def __len__(self):
        return len(self.t)

    def q(self, q, sl: slice) -> np.ndarray:
        s, f = self.seg[sl], self.frac[sl][:, None]
        return q[s] + f * (q[np.minimum(s + 1, len(q) - 1)] - q[s])


def _zone_codes(zone, M) -> np.ndarray:
    z = np.asarray(zone)
    if z.shape != (M,):
        raise BadInput(f"motion check: zone has shape {z.shape}, expected ({M},)")
    if z.dtype.kind in "UO":
        bad = sorted({str(x) for x in z if str(x) not in ZONE_CODE})
        if bad:
            raise BadInput(f"motion check: unknown zone {bad[0]!r} (zones: {', '.join(ZONES)})")
        return np.array([ZONE_CODE[str(x)] for x in z], dtype=np.int64)
    z = z.astype(np.int64)
    if len(z) and (z.min() < 0 or z.max() >= len(ZONES)):
        raise BadInput(f"motion check: zone codes must be 0..{len(ZONES) - 1} (camtool.path.toolpath.ZONES)")
    return z


def chain_bodies(robot, fk: BatchFK, s: MotionCheckSettings) -> list[_Body]:
    """Tool capsule and the last ``s.links`` links (distinct joint origins) before the flange."""
    dof = robot.dof
    offsets = fk.constant_offsets_mm()
    kept = [0]
    for i in range(dof):
        if offsets[i] > 1e-6:
            kept.append(i + 1)
    kept[-1] = dof  # the last distinct point coincides with the flange
    if len(kept) == 1:
        kept = [0, dof]
    links = list(zip(kept[:-1], kept[1:]))[::-1][: int(s.links)]
    names = list(robot.joint_names) + ["flange"]
    tool_len = float(np.linalg.norm(np.asarray(robot.tool_T_mm)[:3, 3]))
    bodies = [_Body("tool", "tool", s.tool_radius_mm, dof, dof + 1, 0.0)]
    chain = tool_len
    for k, (a, b) in enumerate(links):
        role = LINK_ROLES[k] if k < len(LINK_ROLES) else f"link{k + 1}"
        bodies.append(_Body(f"{role} ({names[a]}-{names[b]})", "link", s.link_radius_mm, a, b, chain))
        chain += float(offsets[b - 1])
    return bodies


def _points(fkb, i: int, dof: int) -> np.ndarray:
    if i < dof:
        return fkb.joint_origins[:, i]
    return fkb.flange if i == dof else fkb.tcp


class _Best:
    """Running extreme (min) with the sample and body where it happened."""

    def __init__(self):
        self.value, self.sample, self.body = np.inf, -1, ""

    def offer(self, values: np.ndarray, samples: np.ndarray, body: str | np.ndarray):
        if len(values) == 0:
            return
        k = int(np.argmin(values))
        if values[k] < self.value:
            self.value, self.sample = float(values[k]), int(samples[k])
            self.body = body if isinstance(body, str) else str(body[k])


@dataclass(frozen=True, eq=False)
class WaypointIndex:
    """The caller's index of each waypoint, named in the findings: ``values`` (M,) (-1 = none) called ``label``."""

    values: object
    label: str = "path index"


def check_motion(t_s, q, zone, robot, part: PartGeometry, settings: MotionCheckSettings | None = None,
                 index: WaypointIndex | None = None, *, world=None) -> MotionReport:
    """Measure the joint-linear motion through the waypoints against the part.

    ``t_s`` (M,) strictly increasing waypoint times; ``q`` (M, dof) joint values
    (rad / mm); ``zone`` (M,) zone codes or names (camtool.path.toolpath.ZONES);
    ``robot`` placed (base and tool); ``part`` the placed part;
    ``index`` optional index per waypoint used in the findings
    (``WaypointIndex``, e.g. the segment); ``world`` a
    ``camtool.collision.CollisionWorld``: its pairs (robot and tool bodies x
    obstacles, robot x robot) are measured too (``cell_check``).
    """
    clock = time.perf_counter()
    s = settings or MotionCheckSettings()
    t_s, q, zone, pidx = _motion_inputs(t_s, q, zone, robot, index)
    label = "path index" if index is None else index.label
    fk = BatchFK(robot)
    samples = _Samples(t_s, zone, s.dt_s)
    tcp_wp = _fk_chunks(fk, q, s.chunk_samples)  # the waypoints' TCP: contacts, joint steps per mm on work
    place = _Placer(samples, zone, pidx, label)
    tally = _Tally(part, chain_bodies(robot, fk, s), s, _contact_tree(part, tcp_wp, s), _PerIndex(place.sample_index()))
    cell = _cell_pass_start(world, fk, q, samples) if world is not None and world.pairs else None
    for start in range(0, len(samples), int(s.chunk_samples)):
        sl = slice(start, min(start + int(s.chunk_samples), len(samples)))
        fkb = fk(samples.q(q, sl), frames=cell is not None)
        if cell is not None:
            cell.feed(sl.start, fkb)
        tally.feed(sl, samples.zone[sl], fkb, robot.dof)
    cell_pairs, cell_figures, cell_lines = (), None, []
    if cell is not None:
        cell_pairs, cell_figures, cell_lines = _cell_pass_end(cell, samples, place, s)
    step_rev, step_rev_at, step_pri, step_pri_at = _joint_steps(q, tcp_wp, zone, robot, t_s, pidx, label)
    return MotionReport(
        ok=not cell_lines and tally.passed(), samples=len(samples), dt_s=float(s.dt_s),
        duration_s=float(t_s[-1] - t_s[0]), **tally.figures(place),
        max_joint_step_deg_per_mm=step_rev, max_joint_step_at=step_rev_at,
        max_track_step_mm_per_mm=step_pri, max_track_step_at=step_pri_at,
        findings=tuple(cell_lines + tally.finding_lines(place)), failing_intervals=tally.failing_intervals(samples),
        part=part.describe(), settings=s, check_seconds=time.perf_counter() - clock, horizon_mm=part.horizon_mm,
        cell_pairs=cell_pairs, cell=cell_figures)


def _motion_inputs(t_s, q, zone, robot, index: WaypointIndex | None):
    """(t_s, q, zone codes, the caller's index or None) as arrays; BadInput for a motion the check cannot take."""
    t_s = np.asarray(t_s, dtype=float).reshape(-1)
    M = len(t_s)
    q = np.asarray(q, dtype=float)
    if M == 0:
        raise BadInput("motion check: no waypoints")
    if q.shape != (M, robot.dof):
        raise BadInput(f"motion check: q has shape {q.shape}, expected ({M}, {robot.dof}) for {robot.name}")
    if not (np.isfinite(t_s).all() and np.isfinite(q).all()):
        raise BadInput("motion check: t_s and q must be finite")
    if M > 1 and not (np.diff(t_s) > 0).all():
        k = int(np.nonzero(np.diff(t_s) <= 0)[0][0])
        raise BadInput(f"motion check: waypoint times must increase (t[{k + 1}] = {t_s[k + 1]} after {t_s[k]})")
    zone = _zone_codes(zone, M)
    pidx = None
    if index is not None:
        pidx = np.asarray(index.values).astype(np.int64).reshape(-1)
        if pidx.shape != (M,):
            raise BadInput(f"motion check: path_index has shape {pidx.shape}, expected ({M},)")
    return t_s, q, zone, pidx


def _contact_tree(part, tcp_wp: np.ndarray, s: MotionCheckSettings):
    """A k-d tree of the waypoints whose TCP touches the surface (contacts), or None without one."""
    wp_value = part.signed_distance(tcp_wp)
    touching = np.abs(wp_value) <= s.on_surface_tol_mm
    return cKDTree(tcp_wp[touching]) if touching.any() else None


class _Tally:
    """The check's figures, fed chunk by chunk: the extremes with where they happened, the failing samples,
    and the smallest upper bounds seen so far (``U_tcp``, ``U_body``) that prune the part's queries."""

    def __init__(self, part, bodies: list[_Body], s: MotionCheckSettings, contact_tree, per_index: _PerIndex):
        self.part, self.bodies, self.s, self.G = part, bodies, s, part.horizon_mm
        self.contact_tree, self.per_index = contact_tree, per_index
        self.best_pen = _Best()        # min of c (= -penetration) over all bodies incl. the TCP
        self.best_clear = _Best()      # min clearance, off-work tool + links
        self.best_tcp = _Best()        # min TCP value, off-work, not at contacts
        self.best_dev = _Best()        # min of -|TCP deviation| on work
        self.best_edge = _Best()       # min of -(TCP beyond the part's edge) on work
        self.fails = {"penetration": [], "clearance": [], "deviation": []}
        self.body_pen = {name: _Best() for name in ["tcp"] + [b.name for b in bodies]}
        self.body_clear = {b.name: _Best() for b in bodies}   # off work, against the part
        self.U_body, self.U_tcp = np.inf, np.inf

    def feed(self, sl: slice, zc: np.ndarray, fkb, dof: int) -> None:
        """The samples ``sl``: their zones and forward kinematics; the TCP first, then the capsules."""
        work = zc == WORK
        nonwork = np.isin(zc, np.array(NON_WORK))
        gidx = np.arange(sl.start, sl.stop)
        self._tcp(gidx, fkb.tcp, work, nonwork, np.isin(zc, np.array(SURFACE_CODES)))
        self._capsules(gidx, fkb, dof, work, nonwork)

    def _near_contact(self, tcp: np.ndarray, work: np.ndarray) -> np.ndarray:
        """Off-work samples whose TCP is within the contact allowance of a waypoint touching the surface."""
        s = self.s
        contact = np.zeros(len(tcp), bool)
        if self.contact_tree is not None and s.contact_allowance_mm > 0:
            sel = np.nonzero(~work)[0]
            d, _ = self.contact_tree.query(tcp[sel],
                                           distance_upper_bound=s.contact_allowance_mm * (1 + 1e-9) + 1e-9)
            contact[sel[np.isfinite(d)]] = True
        return contact

    def _tcp_values(self, gidx, tcp, work, eligible):
        """The TCP's surface value and work deviation per sample (inf where pruned); offers the edge overrun."""
        part = self.part
        if eligible.any():
            self.U_tcp = min(self.U_tcp, float(part.upper_bound_distance(tcp[eligible]).min()))
        thr = np.where(work, np.inf, np.where(eligible, max(0.0, min(self.U_tcp, self.G)), 0.0))
        ev = np.nonzero(part.lower_bound(tcp, 0.0) <= thr)[0]
        tv = np.full(len(tcp), np.inf)
        dv = np.full(len(tcp), np.inf)  # work deviation: the value, or beyond the edge the normal offset
        tq = part.query(tcp[ev])
        tv[ev] = tq.value_mm
        dv[ev] = np.where(tq.in_footprint, tq.value_mm, tq.normal_offset_mm)
        out = ev[~tq.in_footprint & work[ev]]
        if len(out):
            lateral = np.sqrt(np.maximum(tq.distance_mm[~tq.in_footprint & work[ev]] ** 2
                                         - tq.normal_offset_mm[~tq.in_footprint & work[ev]] ** 2, 0.0))
            self.best_edge.offer(-lateral, gidx[out], "tcp")
        return tv, dv

    def _tcp(self, gidx, tcp, work, nonwork, on_surface) -> None:
        """The TCP's samples: penetration (within a scan's noise band on work, leads and at contacts), clearance
        off work away from contacts, deviation on work."""
        s = self.s
        contact = self._near_contact(tcp, work)
        eligible = nonwork & ~contact
        tv, dv = self._tcp_values(gidx, tcp, work, eligible)
        self.best_pen.offer(tv, gidx, "tcp")
        self.body_pen["tcp"].offer(tv, gidx, "tcp")
        pen = tv < -np.where(on_surface | contact, s.tcp_surface_tol_mm, s.penetration_tol_mm)
        self.fails["penetration"].append((gidx[pen], np.full(pen.sum(), "tcp"), -tv[pen]))
        el = np.nonzero(eligible & np.isfinite(tv))[0]
        self.best_tcp.offer(tv[el], gidx[el], "tcp")
        if len(el):
            self.U_tcp = min(self.U_tcp, float(tv[el].min()))
        wk = np.nonzero(work)[0]
        self.best_dev.offer(-np.abs(dv[wk]), gidx[wk], "tcp")
        self.per_index.offer(gidx, work, nonwork, tv, np.abs(dv))
        dev = work & (np.abs(dv) > s.work_path_tol_mm)
        self.fails["deviation"].append((gidx[dev], np.full(dev.sum(), "tcp"), dv[dev]))

    def _capsules(self, gidx, fkb, dof, work, nonwork) -> None:
        """The tool's and the links' capsules: penetration everywhere, clearance off work."""
        s = self.s
        cmin, self.U_body = _capsules(self.part, fkb, self.bodies, dof, s, nonwork, self.U_body)
        for b, body in enumerate(self.bodies):
            c = cmin[:, b]
            self.best_pen.offer(c, gidx, body.name)
            self.body_pen[body.name].offer(c, gidx, body.name)
            pen = c < -s.penetration_tol_mm
            self.fails["penetration"].append((gidx[pen], np.full(pen.sum(), body.name, dtype=object), -c[pen]))
            nw = np.nonzero(nonwork)[0]
            self.best_clear.offer(c[nw], gidx[nw], body.name)
            self.body_clear[body.name].offer(c[nw], gidx[nw], body.name)
            low = nonwork & (c < s.clearance_mm) & ~pen
            self.fails["clearance"].append((gidx[low], np.full(low.sum(), body.name, dtype=object), c[low]))
            self.per_index.offer(gidx, work, nonwork, c, None, clearance=True)

    def passed(self) -> bool:
        """True when no sample failed against the part."""
        return not any(self.fails[k][i][0].size for k in self.fails for i in range(len(self.fails[k])))

    def failing_intervals(self, samples: _Samples) -> tuple[tuple[str, str, int, int], ...]:
        """(kind, body, waypoint before, waypoint after) of every failing sample, once each, sorted."""
        out = set()
        for kind, parts in self.fails.items():
            for k, body, _value in parts:
                k = np.asarray(k, np.int64)
                if not len(k):
                    continue
                before = np.where(samples.at_wp[k], samples.wp[k], samples.wp[k] - 1)
                body = np.asarray(body, dtype=object)
                for b in dict.fromkeys(body.tolist()):
                    pairs = np.unique(np.stack([before, samples.wp[k]], axis=1)[body == b], axis=0)
                    out |= {(kind, str(b), int(w0), int(w1)) for w0, w1 in pairs}
        return tuple(sorted(out))

    def finding_lines(self, place: _Placer) -> list[str]:
        """The finding lines against the part: penetration, clearance, deviation."""
        return (_finding_lines(self.fails["penetration"], place, self.s, "penetration")
                + _finding_lines(self.fails["clearance"], place, self.s, "clearance")
                + _finding_lines(self.fails["deviation"], place, self.s, "deviation"))

    def figures(self, place: _Placer) -> dict:
        """The report's figures against the part (``MotionReport`` fields), with where they happened."""
        s, G = self.s, self.G
        best_pen, best_clear, best_tcp, best_dev, best_edge = (self.best_pen, self.best_clear, self.best_tcp,
                                                               self.best_dev, self.best_edge)
        max_pen = max(0.0, -best_pen.value) if np.isfinite(best_pen.value) else 0.0
        min_clear = best_clear.value if best_clear.value <= G else None
        tcp_clear = best_tcp.value if best_tcp.value <= G else None
        dev = -best_dev.value if np.isfinite(best_dev.value) else None
        exact_below = max(s.clearance_mm, min(self.U_body, G))   # no body value at or below it was pruned
        return dict(
            max_penetration_mm=max_pen,
            max_penetration_at=place(best_pen.sample, best_pen.body) if max_pen > 0 else None,
            min_clearance_mm=min_clear,
            min_clearance_at=place(best_clear.sample, best_clear.body) if min_clear is not None else None,
            tcp_min_clearance_mm=tcp_clear,
            tcp_min_clearance_at=place(best_tcp.sample, "tcp") if tcp_clear is not None else None,
            work_deviation_mm=dev, work_deviation_at=place(best_dev.sample, "tcp") if dev is not None else None,
            work_beyond_edge_mm=-best_edge.value if np.isfinite(best_edge.value) else None,
            work_beyond_edge_at=place(best_edge.sample, "tcp") if np.isfinite(best_edge.value) else None,
            bodies=tuple(_body_figures(name, kind, radius, self.body_pen[name], clear, place, exact)
                         for name, kind, radius, clear, exact in
                         [("tcp", "tcp", 0.0, best_tcp, max(0.0, min(self.U_tcp, G)))]
                         + [(b.name, b.kind, b.radius, self.body_clear[b.name], exact_below) for b in self.bodies]),
            by_index=self.per_index.figures(self.fails, G))


def _cell_pass_start(world, fk, q, samples):
    """The cell pass (``cell_check``) over these samples: motion bounds from the waypoints, chunks fed later."""
    from .cell_check import CellPass, between_rows, sampled_motion_bounds

    clock = time.perf_counter()
    cp = CellPass(world, fk, between_rows(lambda k: samples.q(q, k), len(samples)),
                  sampled_motion_bounds(world, q, samples.seg, samples.frac), world.clearance_mm)
    cp.seconds += time.perf_counter() - clock
    return cp


def _cell_pass_end(cp, samples, place, s):
    """Per-pair figures, the world's figures and the finding lines of a fed cell pass."""
    clock = time.perf_counter()
    world, states, S = cp.world, cp.states(), len(samples)
    pairs, lines = [], []
    for pair, st in zip(world.pairs, states):
        a, b = world.pair_name(pair)
        at = place(int(st.best_at), f"{a} x {b}") if st.best_at >= 0 else None
        entry = {"a": a, "b": b, "kind": pair.kind, "min_distance_mm": round(float(st.best), 3),
                 "evaluations": st.evaluations}
        if at is not None:
            entry["at"] = at.to_dict()
            entry["t_s"] = round(float(np.interp(st.best_at, np.arange(S), samples.t)), 6)
            entry["points_mm"] = [[round(float(x), 2) for x in pt] for pt in st.best_points]
        pairs.append(entry)
        if st.fails:
            k = np.array([f[0] for f in st.fails])
            v = np.array([f[1] for f in st.fails])
            runs = np.split(np.arange(len(k)), np.nonzero(np.diff(k) > 1.0 + 1e-9)[0] + 1)
            for run in runs[: s.max_findings_per_kind]:
                i = run[np.argmin(v[run])]
                p = place(int(k[i]), f"{a} x {b}")
                t = float(np.interp(k[i], np.arange(S), samples.t))
                what = (f"{a} and {b} overlap by {-v[i]:.3f} mm" if v[i] < 0 else
                        f"{a} and {b} are {v[i]:.3f} mm apart (< cell.clearance_mm {world.clearance_mm:g} mm)")
                where = p.text().replace(f"t = {p.t_s:.3f} s", f"t = {t:.3f} s", 1)
                near = " at ({:.0f}, {:.0f}, {:.0f}) mm".format(*st.best_points[0]) if len(st.best_points) and \
                    i == int(np.argmin(v)) else ""
                lines.append(f"collision: {what} at {where}{near}")
            if len(runs) > s.max_findings_per_kind:
                lines.append(f"collision: {len(runs) - s.max_findings_per_kind} more intervals for {a} x {b}")
    figures = dict(world.describe(), evaluations=int(sum(st.evaluations for st in states)),
                   seconds=round(cp.seconds + time.perf_counter() - clock, 4))
    return tuple(pairs), figures, lines


def _body_figures(name, kind, radius, pen: _Best, clear: _Best, place, exact_below: float) -> dict:
    """A body's figures: its deepest penetration, and its smallest clearance from the part off
    work with where and when. That clearance is exact up to ``exact_below`` (the check's final
    threshold: pieces farther were pruned); above it only the bound is known."""
    d = {"name": name, "kind": kind, "radius_mm": radius,
         "max_penetration_mm": max(0.0, -pen.value) if np.isfinite(pen.value) else 0.0}
    if clear.value <= exact_below:
        d["min_clearance_mm"] = round(float(clear.value), 6)
        d["min_clearance_at"] = place(clear.sample, name).to_dict()
    else:
        d["min_clearance_mm"], d["clearance_above_mm"] = None, round(float(exact_below), 6)
    return d


def _fk_chunks(fk: BatchFK, q: np.ndarray, chunk: int) -> np.ndarray:
    return np.concatenate([fk(q[i:i + chunk]).tcp for i in range(0, len(q), chunk)])


def _capsules(part, fkb, bodies, dof, s, nonwork, U):
    """Smallest clearance c = value - radius per (sample, body) over the capsule axis samples
    that can matter (inf where every piece was provably above the threshold).

    Each capsule axis is split in halves until pieces are <= radius / 2 long; a
    piece is dropped as soon as the part's lower bound over its ball shows it
    cannot go below the threshold: 0 on work (penetration only), the
    clearance or the smallest clearance seen so far off work.
    """
    n = len(nonwork)
    G = part.horizon_mm
    cmin = np.full((n, len(bodies)), np.inf)
    S_, B_, M_, U_, H_, R_, HL_ = [], [], [], [], [], [], []
    for b, body in enumerate(bodies):
        A = _points(fkb, body.start, dof)
        B = _points(fkb, body.end, dof)
        if body.kind == "tool":
            left = np.full(n, s.tool_contact_exempt_mm)
        else:
            left = np.full(n, max(s.tool_contact_exempt_mm - body.exempt_before, 0.0))
        axis = B - A
        L = np.linalg.norm(axis, axis=1)
        u = axis / np.maximum(L, 1e-12)[:, None]
        L2 = L - np.minimum(left, L)
        keep = L2 > 1e-9
        if not keep.any():
            continue
        idx = np.nonzero(keep)[0]
        h = L2[idx] / 2.0
        r = body.radius
        levels = np.ceil(np.log2(np.maximum(h / max(r / 4.0, MIN_HALF_PIECE_MM), 1.0)))
        zero = np.zeros(len(idx))
        # the axis: pieces split down to <= r/2 long, evaluated at their middles; plus both ends
        S_ += [idx, idx, idx]
        B_.append(np.full(3 * len(idx), b))
        M_ += [A[idx] + u[idx] * h[:, None], A[idx], A[idx] + u[idx] * L2[idx, None]]
        U_ += [u[idx]] * 3
        H_ += [h, zero, zero]
        R_.append(np.full(3 * len(idx), r))
        HL_ += [h / 2.0**levels, zero, zero]
    if not S_:
        return cmin, U
    si, bi = np.concatenate(S_), np.concatenate(B_)
    M, u, h, r, hl = (np.concatenate(x) for x in (M_, U_, H_, R_, HL_))
    while len(si):
        lb = part.lower_bound(M, h) - r
        nw = nonwork[si]
        if nw.any():
            pt = M[nw] - u[nw] * np.where(h[nw] > hl[nw] * (1 + 1e-9), hl[nw], 0.0)[:, None]
            U = min(U, float((part.upper_bound_distance(pt) - r[nw]).min()))
        thr = np.where(nw, max(s.clearance_mm, min(U, G)), 0.0)
        keep = lb <= thr
        leaf = keep & (h <= hl * (1 + 1e-9))
        at = np.nonzero(leaf)[0]  # a tighter (dearer) bound first: the exact query is dearer far from the part
        keep[at[part.above(M[at], 0.0, thr[at] + r[at])]] = False
        leaf &= keep
        if leaf.any():
            c = part.signed_distance(M[leaf]) - r[leaf]
            np.minimum.at(cmin, (si[leaf], bi[leaf]), c)
            nwl = nonwork[si[leaf]]
            if nwl.any():
                U = min(U, float(c[nwl].min()))
        split = keep & ~leaf
        if not split.any():
            break
        hs = h[split] / 2.0
        us = u[split]
        Ms = M[split]
        si = np.concatenate([si[split], si[split]])
        bi = np.concatenate([bi[split], bi[split]])
        M = np.concatenate([Ms - us * hs[:, None], Ms + us * hs[:, None]])
        u = np.concatenate([us, us])
        h = np.concatenate([hs, hs])
        r = np.concatenate([r[split], r[split]])
        hl = np.concatenate([hl[split], hl[split]])
    return cmin, U


class _Placer:
    """Place of a sample: time, zone, the waypoint it moves towards and the caller's index there."""

    def __init__(self, samples: _Samples, zone, pidx, label):
        self.samples, self.label = samples, label
        self.pidx = pidx
        if pidx is not None:
            M = len(pidx)
            valid = pidx >= 0
            pos = np.arange(M)
            nxt = np.where(valid, pos, M)
            self.next = np.minimum.accumulate(nxt[::-1])[::-1]
            prv = np.where(valid, pos, -1)
            self.prev = np.maximum.accumulate(prv)

    def sample_index(self) -> np.ndarray | None:
        """The caller's index of every sample, as ``__call__`` places it (-1: none); None without one."""
        if self.pidx is None:
            return None
        M = len(self.pidx)
        at = np.where(self.pidx >= 0, self.pidx,
                      np.where(self.next < M, self.pidx[np.minimum(self.next, M - 1)],
                               np.where(self.prev >= 0, self.pidx[np.maximum(self.prev, 0)], -1)))
        return at[self.samples.wp]

    def __call__(self, k: int, body: str) -> Place | None:
        if k < 0:
            return None
        sm = self.samples
        wp = int(sm.wp[k])
        at = bool(sm.at_wp[k])
        if self.pidx is None:
            index, rel, label = wp, "at" if at else "before", "waypoint"
        else:
            label = self.label
            if self.pidx[wp] >= 0:
                index, rel = int(self.pidx[wp]), "at" if at else "before"
            elif self.next[wp] < len(self.pidx):
                index, rel = int(self.pidx[self.next[wp]]), "before"
            elif self.prev[wp] >= 0:
                index, rel = int(self.pidx[self.prev[wp]]), "after"
            else:
                index, rel = None, ""
        return Place(float(sm.t[k]), ZONES[int(sm.zone[k])], wp, at, index, label, rel, body)


class _PerIndex:
    """The worst figures of the samples of each caller's index (e.g. segment), fed chunk by chunk:
    the deepest penetration of any body into the part, the work deviation, the off-work clearance."""

    def __init__(self, sample_index: np.ndarray | None):
        self.at = sample_index
        n = int(sample_index.max()) + 1 if sample_index is not None and len(sample_index) else 0
        self.samples = np.bincount(sample_index[sample_index >= 0], minlength=n) if n else np.zeros(0, np.int64)
        self.value = np.full(n, np.inf)       # min signed distance to the part, any body (< 0: penetration)
        self.deviation = np.full(n, -np.inf)  # max |TCP deviation| on work
        self.clearance = np.full(n, np.inf)   # min clearance off work, tool and links

    def offer(self, gidx, work, nonwork, value, deviation, clearance: bool = False) -> None:
        """One body's values over the chunk's samples ``gidx``; ``deviation`` the TCP's (None for a capsule)."""
        if not len(self.value):
            return
        at = self.at[gidx]
        known = (at >= 0) & np.isfinite(value)
        np.minimum.at(self.value, at[known], value[known])
        if deviation is not None:
            w = (at >= 0) & work & np.isfinite(deviation)
            np.maximum.at(self.deviation, at[w], deviation[w])
        if clearance:
            c = known & nonwork
            np.minimum.at(self.clearance, at[c], value[c])

    def figures(self, fails: dict, horizon_mm: float) -> tuple[dict, ...]:
        """Per index with samples: samples, max_penetration_mm, work_deviation_mm (None: no work),
        min_clearance_mm (None: beyond the part's horizon) and the failing samples of each kind."""
        if not len(self.value):
            return ()
        failing = {}
        for kind, parts in fails.items():
            k = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0, np.int64)
            k = np.unique(k.astype(np.int64))
            at = self.at[k]
            failing[kind] = np.bincount(at[at >= 0], minlength=len(self.value))
        out = []
        for i in np.nonzero(self.samples)[0]:
            clear = self.clearance[i]
            out.append({"index": int(i), "samples": int(self.samples[i]),
                        "max_penetration_mm": round(max(0.0, -float(self.value[i])) if np.isfinite(self.value[i])
                                                    else 0.0, 6),
                        "work_deviation_mm": round(float(self.deviation[i]), 6) if np.isfinite(self.deviation[i])
                        else None,
                        "min_clearance_mm": round(float(clear), 6) if clear <= horizon_mm else None,
                        "failing_samples": {kind: int(f[i]) for kind, f in failing.items()}})
        return tuple(out)


def _finding_lines(parts, place: _Placer, s: MotionCheckSettings, kind: str) -> list[str]:
    """One line per run of consecutive failing samples of one body (its worst sample)."""
    idx = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0, np.int64)
    if not len(idx):
        return []
    body = np.concatenate([np.asarray(p[1], dtype=object) for p in parts])
    val = np.concatenate([p[2] for p in parts])
    lines = []
    for name in dict.fromkeys(body.tolist()):
        sel = body == name
        k, v = idx[sel], val[sel]
        order = np.argsort(k, kind="stable")
        k, v = k[order], v[order]
        runs = np.split(np.arange(len(k)), np.nonzero(np.diff(k) > 1)[0] + 1)
        for run in runs[: s.max_findings_per_kind]:
            if kind == "penetration":
                j = run[np.argmax(v[run])]
                what = f"part penetrated by {v[j]:.3f} mm"
                if name == "tcp" and s.scan_band_mm > 0 and v[j] > s.tcp_surface_tol_mm:
                    what += (f" (beyond the scan's noise band: {s.penetration_tol_mm:g} + "
                             f"{s.scan_band_mm:.3f} mm on work and leads)")
            elif kind == "clearance":
                j = run[np.argmin(v[run])]
                what = f"clearance {v[j]:.3f} mm < {s.clearance_mm:g} mm"
            else:
                j = run[np.argmax(np.abs(v[run]))]
                side = "in front of" if v[j] > 0 else "behind"
                tol = f"{s.work_path_tol_mm:.3f} mm, the scan's noise band {s.scan_band_mm:.3f} mm included" \
                    if s.scan_band_mm > 0 else f"{s.path_tol_mm:g} mm"
                what = f"TCP {abs(v[j]):.3f} mm {side} the surface on work (> {tol})"
            p = place(int(k[j]), name)
            t0, t1 = place.samples.t[k[run[0]]], place.samples.t[k[run[-1]]]
            span = f"; from t = {t0:.3f} to {t1:.3f} s" if len(run) > 1 else ""
            lines.append(f"{what} at {p.text()} (body: {name}{span})")
        if len(runs) > s.max_findings_per_kind:
            lines.append(f"{kind}: {len(runs) - s.max_findings_per_kind} more intervals for body {name}")
    return lines


def _joint_steps(q, tcp_wp, zone, robot, t_s, pidx, label):
    """Largest joint step per mm of TCP travel between consecutive work waypoints:
    (deg/mm of revolute joints, place, mm/mm of prismatic joints, place)."""
    if len(q) < 2:
        return None, None, None, None
    both = (zone[:-1] == WORK) & (zone[1:] == WORK)
    travel = np.linalg.norm(np.diff(tcp_wp, axis=0), axis=1)
    sel = np.nonzero(both & (travel > 1e-6))[0]
    if not len(sel):
        return None, None, None, None
    dq = np.abs(np.diff(q, axis=0))[sel]
    prism = np.asarray(robot.prismatic, bool)
    ratio = np.where(prism, dq, np.degrees(dq)) / travel[sel, None]
    out = []
    for mask in (~prism, prism):
        if not mask.any():
            out += [None, None]
            continue
        r = np.where(mask, ratio, -np.inf)
        i, j = np.unravel_index(int(np.argmax(r)), r.shape)
        wp = int(sel[i] + 1)
        index, rel = (wp, "at") if pidx is None else (int(pidx[wp]) if pidx[wp] >= 0 else None, "at")
        out += [float(r[i, j]), Place(float(t_s[wp]), "work", wp, True, index,
                                      "waypoint" if pidx is None else label, rel, robot.joint_names[j])]
    return out[0], out[1], out[2], out[3]
