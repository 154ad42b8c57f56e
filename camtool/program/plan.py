"""Program moves from a timed trajectory: what the RAPID and INFORM writers share.

A controller does not replay a trajectory sample by sample: it interpolates
between the targets of its motion instructions (joint-linear for ``MoveAbsJ`` /
``MOVJ``, a straight TCP line for ``MoveL`` / ``MOVL``) and rounds the corners
of moves that carry a zone (``z…``) or a position level (``PL>0``). So the
writers do not write one move per waypoint; ``plan_moves`` picks the waypoints
that become move targets:

- **Anchors** are always targets: the first and last waypoint, the first and
  last point of every work row (where the process switches on and off) and
  every retract pose (and, for linear moves, where straight moves start or
  stop: process zones away from singularities, ``MIN_DEXTERITY``).
- **The planned motion.** A step whose joint-linear chord bows off the planned
  motion by more than ``DENSIFY_SHARE`` of the tolerance gets waypoints on the
  planned motion (the trajectory's quintic pieces).
- **Merging.** Between anchors, a Douglas-Peucker pass keeps the fewest
  waypoints such that the controller's interpolation between consecutive
  targets stays within ``MERGE_SHARE`` of the path tolerance of every planned
  waypoint it skips (``ProcessInfo.path_tol_mm`` on the process zones, that
  times ``FREE_TOL_FACTOR`` in free motion). For joint moves the distance is
  measured in TCP mm, first with each waypoint's TCP Jacobian, then exactly
  (batch forward kinematics); for linear moves it is the TCP's distance from
  the straight line, and the tool orientation's deviation from the slerp
  (``ProcessInfo.ori_tol_deg``). On work a waypoint is also kept where the
  move's single pace would lead or lag the plan by more than ``FEED_LAG_MM``
  (``FeedKeeper``). Where a format's Cartesian targets also state joints (``held``: the
  SIA20D's E axis, a track), which the controller moves linearly in a straight move, a
  straight move skips a waypoint only while the joints it solves stay within
  ``HELD_JOINT_GUARD`` of the plan's there (``HeldJointChords``); the post stage writes
  joint moves over spans its simulator finds the controller cannot follow
  (``ProcessInfo.joint_moves_s``), and, where it finds the program farther from the planned
  path than it aims for, merges and blends the moves of those spans within a share of the
  tolerance (``ProcessInfo.closer_s``: every tolerance above, and the arcs', scaled there).
- **Blending.** Every target but the first, the last and the top of each
  retract gets the largest blend level (zone radius in mm) whose corner
  rounding stays within ``BLEND_SHARE`` of the tolerance (a chord deviates
  most in the middle of its move, a corner at its target, and between them
  both fall off about quadratically, so the two do not add up). The model is
  the simulator's: a parabolic blend over equal times before and after the
  target, cutting at most r and at most half of either move, so it deviates by
  a quarter of the difference of the two cut vectors. Where even the smallest
  level cuts a corner of the surface too much, the moves beside it are
  shortened (a skipped waypoint, or a point of the planned motion near the
  corner, becomes a target) until it fits.
- **Splitting.** Long programs are split into parts (modules, jobs) only
  after a target off the surface (outside every row), never on it
  (``split_parts``).

Timing is the planned time of each target; the writers turn it into ``\\T``,
VJ or a TCP speed.

The stages, each in its own module and each a declared step: ``candidates`` (the
waypoints; ``AddPlannedPoints``, ``MarkAnchors``, ``MergeChords``), ``blend``
(``BlendCorners``: levels, shorter moves beside tight corners, rows), then the move-list
steps of ``steps`` (``ExactStops`` here; ``JoinNullLinear`` and ``FitArcs`` in the
writers). ``moveplan`` holds the data they pass on.
"""
from __future__ import annotations

import numpy as np

from camtool.errors import BadInput

from .blend import BlendCorners
from .candidates import merged_candidates
from .moveplan import KIND_CIRCULAR, KIND_JOINT, KIND_LINEAR, MovePlan  # noqa: F401 (what the writers read)
from .steps import ExactStops, context_for, program_steps


def plan_moves(trajectory, robot, process, *, linear: bool, levels_mm, min_level_on_surface: int = 0,
               max_level: int | None = None, held=()) -> MovePlan:
    """Pick the move targets of a program (see module doc): the merged candidates, their
    corners blended, the exact stops.

    ``linear`` True plans straight TCP moves on the process zones (work, leads) and joint
    moves in free motion; False plans joint moves everywhere. ``levels_mm`` are the
    format's blend radii (ascending, all > 0); a corner on the surface never gets less than
    ``min_level_on_surface`` (never an exact stop there); ``max_level`` caps the level.
    ``wp`` of the plan indexes the trajectory's waypoints, with targets added on the planned
    motion (between waypoints) where a corner needed shorter moves (-1 there). ``held``: the joints
    (indices) the format's Cartesian targets state (a 7th axis, a track), which the controller moves
    linearly in a straight move: straight moves are merged only while the joints it solves stay near
    the plan's (``candidates.HeldJointChords``).
    """
    candidates = merged_candidates(trajectory, robot, process, linear, held)
    plan = BlendCorners(tuple(np.asarray(levels_mm, float).tolist()), min_level_on_surface).plan(candidates)
    return ExactStops(min_level_on_surface, max_level).apply(plan)


def planned_moves(trajectory, robot, process, *, linear: bool, levels_mm, min_level_on_surface: int = 0,
                  held=(), arcs_max_sweep_deg: float | None = None, arc_start_linear: bool = False) -> MovePlan:
    """A writer's moves: ``plan_moves`` within the format's blend radii, then the program steps
    (``steps.program_steps``: null linear moves, and circles as circular moves with ``arcs_max_sweep_deg``)."""
    plan = plan_moves(trajectory, robot, process, linear=linear, levels_mm=levels_mm,
                      min_level_on_surface=min_level_on_surface, held=held)
    steps = program_steps(arcs_max_sweep_deg=arcs_max_sweep_deg, arc_start_linear=arc_start_linear)
    return steps.apply(plan, context_for(trajectory, robot, process, plan, levels_mm, min_level_on_surface))


def stop_at_part_ends(level: np.ndarray, parts: list[range]) -> np.ndarray:
    """Each move's level, -1 (an exact stop) at the end of every part but the last: the program
    calls (or loads) the next part there, which ends the motion."""
    level = np.array(level, copy=True)
    for r in parts[:-1]:
        level[r.stop - 1] = -1
    return level


def row_markers(plan: MovePlan, process, start_lines, end_lines) -> tuple[dict[int, list[str]], dict[int, list[str]]]:
    """A format's lines before a row's first move and after its last one, by move index:
    ``start_lines(row_no, label)`` (label: the row's from ``process.row_labels``, or None) and
    ``end_lines(row_no)``; rows count from 1."""
    labels = list(process.row_labels)
    before: dict[int, list[str]] = {}
    after: dict[int, list[str]] = {}
    for i in np.flatnonzero(plan.row_start | plan.row_end):
        row_no = int(plan.row[i]) + 1
        if plan.row_start[i]:
            before[i] = start_lines(row_no, labels[row_no - 1] if row_no - 1 < len(labels) else None)
        if plan.row_end[i]:
            after[i] = end_lines(row_no)
    return before, after


def move_lengths(plan: MovePlan) -> np.ndarray:
    """(n,) TCP path length of each move (mm): its line, or for a circular move its arc; 0 for
    the first (from wherever the robot is)."""
    from .arcs import circle_through

    length = np.r_[0.0, np.linalg.norm(np.diff(plan.P, axis=0), axis=1)]
    circ = np.flatnonzero(np.asarray(plan.kind) == KIND_CIRCULAR)
    circ = circ[circ > 0]
    if len(circ):
        c, rad, n, r0, sweep, ok = circle_through(plan.P[circ - 1], plan.via_P[circ], plan.P[circ])
        length[circ] = np.where(ok, rad * sweep, length[circ])
    return length


def profile_tool(profile) -> np.ndarray:
    """The TCP (4 x 4, mm, flange frame) of a profile's tool: what the program's Cartesian
    targets refer to."""
    from camtool.transforms import matrix_from_xyz_rpy

    return matrix_from_xyz_rpy(profile.tool["tcp_xyz_mm"], profile.tool["tcp_rpy_deg"])


def split_parts(n: int, limit: int, allowed_after: np.ndarray, what: str, where: str) -> list[range]:
    """Split n items into consecutive parts of at most ``limit``, each part (but the last)
    ending on an item after which a split is allowed (``allowed_after[i]``: after item i).

    BadInput naming ``what`` and ``where`` when some stretch between allowed points is longer
    than ``limit``.
    """
    parts, s = [], 0
    allowed = np.flatnonzero(np.asarray(allowed_after, bool))
    while n - s > limit:
        hi = s + limit - 1  # the last item that fits in this part
        cand = allowed[(allowed >= s) & (allowed <= hi)]
        cand = cand[cand < n - 1]
        if not len(cand):
            raise BadInput(f"{where}: more than {limit} {what} between two points off the surface (from item "
                           f"{s + 1}); raise the option or loosen post.path_tol_mm")
        e = int(cand[-1]) + 1
        parts.append(range(s, e))
        s = e
    parts.append(range(s, n))
    return parts


def part_names(name: str, count: int, max_len: int) -> list[str]:
    """The names of a split program's parts: ``name`` cut so that ``_1``, ``_2``, ... fits in ``max_len``."""
    return [name[:max_len - len(f"_{k}")] + f"_{k}" for k in range(1, count + 1)]


def round_durations(dt: np.ndarray, resolution: float, fastest: np.ndarray | None = None) -> np.ndarray:
    """Durations on a grid of ``resolution`` whose running sum tracks the planned one (error
    diffusion): each written duration is the planned one rounded up or down so that the
    program's clock never drifts by more than one step. ``fastest`` (optional) is the
    shortest duration each move may take (a speed limit); no written value is below it
    (rounded up to the grid), and never below one step."""
    dt = np.asarray(dt, float)
    out = np.empty_like(dt)
    floor_ = np.full(len(dt), resolution) if fastest is None else np.maximum(resolution, fastest)
    planned = 0.0
    written = 0.0
    for i, d in enumerate(dt):
        planned += d
        ticks = round((planned - written) / resolution)
        v = ticks * resolution
        lo = np.ceil(floor_[i] / resolution - 1e-9) * resolution
        v = max(v, lo)
        out[i] = v
        written += v
    return out
