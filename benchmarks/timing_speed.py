"""Time a synthetic seed8 job of many work runs; print wall time, cycle time and peak RSS.

Usage: .venv/bin/python benchmarks/timing_speed.py [n_runs] [poses_per_run] [method] [zones (flow)]

"timing+check" is ``time_trajectory`` (which resamples once and checks); the
report reuses what the check gathered of those samples (``sampled``), as the pipeline does.
"""
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_timing_fixtures import joint_path_and_path, seed8, two_runs  # noqa: E402

from camtool.settings import TimingSettings  # noqa: E402
from camtool.timing import time_trajectory, timing_report  # noqa: E402
from camtool.path.toolpath import ZONE_CODE  # noqa: E402


def main():
    n_runs = int(sys.argv[1]) if len(sys.argv) > 1 else 80
    per_run = int(sys.argv[2]) if len(sys.argv) > 2 else 125
    method = sys.argv[3] if len(sys.argv) > 3 else "quintic"
    zones = sys.argv[4] if len(sys.argv) > 4 else "flow"
    settings = TimingSettings.make(method=method, zones=zones)
    robot = seed8()
    jp, _ = two_runs(robot, n=per_run, pitch_mm=400.0 / per_run)
    block_q, block_z = jp.q[: per_run + 2], jp.zone[: per_run + 2]
    q = np.vstack([block_q] * n_runs)
    zone = np.tile(block_z, n_runs)
    seg = np.repeat(np.arange(n_runs), per_run + 2)
    jp, path = joint_path_and_path(robot, q, zone, seg)
    t0 = time.perf_counter()
    tr = time_trajectory(jp, path, robot, settings)
    wall = time.perf_counter() - t0
    t1 = time.perf_counter()
    rep = timing_report(tr, robot, tr.sampled)
    wall_report = time.perf_counter() - t1
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"poses {len(q)} work {int((zone == ZONE_CODE['work']).sum())} method {method} zones {zones}: "
          f"timing+check {wall:.2f} s, report {wall_report:.2f} s, waypoints {len(tr.t_s)}, cycle {rep['cycle_time_s']:.1f} s, "
          f"work {rep['work_time_s']:.1f} s, peaks v/a/j {rep['peak_joint_speed_ratio']:.3f}/"
          f"{rep['peak_joint_acc_ratio']:.3f}/{rep['peak_joint_jerk_ratio']:.3f}, "
          f"slowdowns {len(rep['slowdowns'])}, ruckig pieces {100 * rep['ruckig_piece_share']:.1f} % "
          f"(fallbacks {rep['ruckig_fallbacks']['by_reason']}), peak RSS {rss_mb:.0f} MB")


if __name__ == "__main__":
    main()
