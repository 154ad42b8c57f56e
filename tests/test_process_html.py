"""camtool.process.html and the verdict of report.html."""
import numpy as np

from camtool.process.figures import map_figures, save_map_npz
from camtool.process.html import process_heat_map_figure, process_note
from camtool.report.html import _verdict_rows
from tests.test_process_figures import known_map
from tests.test_process_integrate import plate


def test_heat_map_on_the_surface_from_the_npz(tmp_path):
    pm = known_map(lambda U, V: 1.0 + 0.001 * U)
    figures = {**map_figures(pm), "file": str(save_map_npz(pm, tmp_path / "process_map.npz"))}
    fig = process_heat_map_figure(figures, plate(100, 60))
    trace = fig.data[0]
    assert trace.type == "surface"
    color = np.asarray(trace.surfacecolor, float)
    assert np.nanmax(color) > np.nanmin(color) and np.isnan(color).any()  # off-material cells left out
    assert "within ±5 %" in process_note(figures)
    assert process_heat_map_figure({"file": str(tmp_path / "missing.npz")}, plate()) is None


def test_verdict_rows_say_what_failed():
    ok = dict(_verdict_rows({"status": "ok", "cycle_time_s": 100.0, "work_time_s": 80.0,
                             "work_feed": {"work_share_within_1pct": 1.0, "work_length_mm": 5000.0,
                                           "commanded_feed_mm_s": 100.0, "min_work_feed_mm_s": 99.9},
                             "process_map": {"mean": 2.0, "uniformity_within_5pct": 0.96, "units": "um",
                                             "uniformity_target": 0.95, "meets_uniformity_target": True}}))
    assert ok["Status"] == "ok" and "100.0 s" in ok["Cycle time"] and "within 1 %" in ok["Feed held"]
    assert "96.0 %" in ok["Process uniformity"] and "met" in ok["Process uniformity"]
    assert "Where it failed" not in ok
    bad = dict(_verdict_rows({"status": "unsafe", "reason": "the motion check failed",
                              "motion_check": {"min_clearance_mm": 1.0, "findings": ["wrist 1 mm from the part"]}}))
    assert "unsafe" in bad["Status"] and "wrist 1 mm" in bad["Where it failed"]
    assert "Closest approach to the part" in bad and bad["Closest approach to the cell"].startswith("no cell")
    cell = dict(_verdict_rows({"status": "ok", "motion_check": {"cell_pairs": [
        {"a": "forearm", "b": "table", "min_distance_mm": 42.0}, {"a": "tool", "b": "floor", "min_distance_mm": 80.0}]}}))
    assert cell["Closest approach to the cell"].startswith("42.0 mm (forearm x table")
    # link against link is its own row: a self pair is never shown as the approach to the cell
    mixed = dict(_verdict_rows({"status": "ok", "motion_check": {"cell_pairs": [
        {"a": "carriage", "b": "j6-j7", "kind": "self", "min_distance_mm": 23.7}]}}))
    assert mixed["Closest approach to the cell"].startswith("no cell")
    assert mixed["Closest approach between links"].startswith("23.7 mm (carriage x j6-j7, 1 pairs")
