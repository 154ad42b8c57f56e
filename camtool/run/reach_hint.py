"""A reach hint that works (issue #48): the placement a reach failure prints has been planned and timed.

``nearest_feasible_shift`` (``placement/shift.py``) finds the nearest placement at which the closed-form screen
reaches every pose; the screen does not keep the path continuous, size the leads or time the runs, so such a
placement may still fail (a scanned dome moved by its hint failed in timing). ``planned_shift`` runs the plan
and time stages of the job at that placement (the workpiece read, fitted and rastered there, as ``camtool run``
would) and prints it only if they pass within the joints' limits; else it asks the screen again with wider
margins (``HINT_MARGINS``), and if none plans, it names no placement (``camtool place`` searches further).
Where the screen finds no placement at any of those margins, it is asked once more without margins
(``LAST_MARGINS``: a narrow window, as the IRB2400's wrist bend leaves the noether panel scan), that placement
planned before it is printed; where it finds none even so, the refusal says so (``NOWHERE``). Where it names
no placement, it names ``camtool place`` (``PLACE``), which also tilts the part (``placement/tilt.py``): the
shift's screen only moves and turns it about z.
The number of placements tried is fixed (no clock): the same job gives the same hint.
"""
from __future__ import annotations

import dataclasses

from ..errors import CamtoolError
from ..job import Section
from ..placement.shift import ShiftSearch, nearest_feasible_shift
from ..placement.tilt import DEFAULT_MAX_DEG
from ..timing import limit_findings
from ..timing.pathlaw import remembered_runs
from .job_settings import JobSettings

HINT_MARGINS = ((0.02, 0.02), (0.05, 0.05), (0.10, 0.08))  # (reach, joint) margins of the screen, in order
LAST_MARGINS = (0.0, 0.0)   # where none of those finds a placement: the screen without margins (a narrow window,
                            # as the noether panel's for the IRB2400's wrist bend), planned before it is printed
PLACE = ("camtool place searches wider (--vary) and, where no upright placement plans, tilts the part on its "
         f"fixture (roll, pitch up to --tilt-max-deg, {DEFAULT_MAX_DEG:g} deg unless given)")
NOWHERE = "no placement within {mm:g} mm (nor turned about z) reaches every pose in the closed-form screen; " + PLACE
SCREENED = "reaches every pose in the closed-form screen (camtool place searches further)"
PLANNED = "plans and times every pose (tried)"


def placed(job, shift: dict):
    """``job`` with the workpiece at the shift's placement."""
    sections = dict(job.sections)
    sections["cell"] = Section({**job.sections["cell"], "workpiece_xyz_mm": list(shift["workpiece_xyz_mm"]),
                                "workpiece_rpy_deg": list(shift["workpiece_rpy_deg"])})
    return dataclasses.replace(job, sections=sections)


def why_not_planned(job) -> str | None:
    """None when ``job``'s plan and time stages pass (no unreachable pose, the trajectory within the limits);
    else why not, in one line."""
    from .stages import (part_for_checks, path_for_job, plan_with_sized_leads, robot_for_job, surface_for_job,
                         time_for_job, workpiece_for_job)

    try:
        robot = robot_for_job(job)
        settings = JobSettings.from_job(job, robot)
        wp = workpiece_for_job(job)
        surface = surface_for_job(job, wp)
        path = path_for_job(job, surface)
        with remembered_runs():  # as the raster task plans and times
            path, jp = plan_with_sized_leads(settings, surface, path, robot, part_for_checks(settings, wp, surface))
            trajectory = time_for_job(settings, jp, path, robot)
    except CamtoolError as exc:
        return str(exc)
    findings = limit_findings(trajectory, robot, settings.timing.check_dt_s)
    return f"the timed trajectory breaks {len(findings)} limit(s); first: {findings[0]}" if findings else None


def planned_shift(job, settings, robot, path, margins=HINT_MARGINS) -> dict | None:
    """The nearest placement that reaches every pose in the screen and plans and times (module doc): the dict of
    ``nearest_feasible_shift`` with ``planned`` (True, or False with ``not_planned``: why the last one tried did
    not) and its message; None where the screen finds nothing."""
    tried: dict = {}
    first = last = None
    for k, (reach_margin, joint_margin) in enumerate((*margins, LAST_MARGINS)):
        if k == len(margins) and (first is not None or last is not None):
            break   # the margins found placements: their answer stands
        shift = nearest_feasible_shift(job, settings, robot, path,
                                       ShiftSearch(reach_margin=reach_margin, joint_margin=joint_margin))
        first = shift if first is None else first
        if shift is None or shift["already_reachable"]:
            continue  # the screen passes this placement, which failed: wider margins may move it
        key = (tuple(shift["workpiece_xyz_mm"]), tuple(shift["workpiece_rpy_deg"]))
        if key not in tried:
            tried[key] = why_not_planned(placed(job, shift))
        if tried[key] is None:
            return {**shift, "planned": True, "message": shift["message"].replace(SCREENED, PLANNED)}
        last = {**shift, "planned": False, "not_planned": tried[key],
                "message": f"none of the {len(tried)} nearest placements the closed-form screen reaches plans too "
                           f"(report.json: nearest_feasible_shift; the last fails: {tried[key]}); {PLACE}"}
    return last if last is not None else first
