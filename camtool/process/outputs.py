"""The run's process hook: the map of the timed trajectory, its files and report.json figures.

    figures, files = process_outputs(job, settings, trajectory, robot, surface, outdir)

``figures`` goes under report.json's ``process_map``; ``files`` are
``process_map.npz`` (beside report.json) and ``plots/process_map.png``; a job of several faces
(``faces.select``) has a map per face too (``process_map_face<N>.npz``, ``plots/process_map_face<N>.png``,
its figures under ``faces``) and the headline figures are those of all of them (``map_set``). The
time the map took is reported (``seconds`` wall, ``cpu_seconds`` of this process) so its share of the run can be
measured. A job without a process (``process.kind = "none"``) gets nothing.
"""
from __future__ import annotations

import time
from pathlib import Path

from .figures import map_figures, plot_map_png, save_map_npz
from .map_set import FACE_FILE, FACE_PNG
from .maps import trajectory_surface_map

MAP_FILE = "process_map.npz"
PNG_FILE = "plots/process_map.png"


def _meets(figures: dict, process) -> bool:
    return bool(figures.get("mean") is not None and figures["uniformity_within_band"] >= process.uniformity_target)


def _face_outputs(job, process, index: int, pmap, outdir: Path, files: list) -> dict:
    """One face's figures (of several in one program) and its files, appended to ``files``."""
    figures = map_figures(pmap, process.uniformity_band)
    made = [save_map_npz(pmap, outdir / FACE_FILE.format(index=index)),
            plot_map_png(pmap, figures, outdir / FACE_PNG.format(index=index),
                         title=f"{job.path.name}, face {index} ({pmap.grid.surface.model}): {pmap.quantity}")]
    files += made
    return {"index": index, "model": pmap.grid.surface.model, **figures, "file": str(made[0]), "png": str(made[1]),
            "meets_uniformity_target": _meets(figures, process)}


def process_outputs(job, settings, trajectory, robot, surface, outdir, extra: dict | None = None, dwell=None
                    ) -> tuple[dict | None, list[Path]]:
    """(figures, files) of the job's process map, or (None, []) without a process or a surface.

    ``dwell``: the ``DwellPlan`` the trajectory was timed with (a target removal map); its figures and the
    run's residual against the target go under ``target``."""
    process = settings.process
    if process is None or not process.enabled or surface is None:
        return None, []
    start, cpu = time.perf_counter(), time.process_time()
    grid = None if dwell is None else dwell.before.grid
    pmap = trajectory_surface_map(process, surface, trajectory, robot, settings.check.dt_s, sites=grid,
                                  rows_mm=float(settings.raster.step_over_mm))
    figures = map_figures(pmap, process.uniformity_band)
    outdir = Path(outdir)
    files = [save_map_npz(pmap, outdir / MAP_FILE),
             plot_map_png(pmap, figures, outdir / PNG_FILE, title=f"{job.path.name}: {pmap.quantity}")]
    figures["file"] = str(files[0])
    figures["png"] = str(files[1])
    figures["footprint"] = {"profile": process.profile, "diameter_mm": process.diameter_mm}
    figures["uniformity_target"] = process.uniformity_target
    figures["uniformity_band_pct"] = round(100 * process.uniformity_band, 6)
    figures["meets_uniformity_target"] = _meets(figures, process)
    faces = [_face_outputs(job, process, index, face_map, outdir, files) for index, face_map in pmap.grid.per_face()]
    if faces:
        figures["faces"] = faces
    if extra:
        figures.update(extra)
    if dwell is not None:
        from .dwell import run_residual

        figures["target"] = {**dwell.figures, **run_residual(dwell, pmap.values, 0.5 * process.diameter_mm)}
    figures["seconds"] = round(time.perf_counter() - start, 3)
    figures["cpu_seconds"] = round(time.process_time() - cpu, 3)  # the share of the run, whatever else runs
    return figures, files

