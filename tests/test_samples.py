"""Every shipped sample job runs end to end: `camtool run samples/X.toml -o DIR` exits 0 (every
check on, as a user runs it).

Marked ``samples`` and run only when selected (``pytest -m samples tests/test_samples.py``): each
sample is a whole run, minutes in all, so a plain ``pytest`` skips them.

- A sample that fails for a known bug is listed in ``XFAIL`` (xfail(strict=True)), so its fix shows as an
  unexpected pass to remove the mark. The SIA20 walls (issue #48) run now: a scan outlier had tilted the
  motion check's local plane.
- A job with ``fit.model = "freeform"`` skips where ``camtool fit`` refuses that key. The free-form hood
  (samples/freeform_hood.toml) and the noisy shell scan (samples/freeform_shell_scan.toml) run; a free-form
  job that does not run yet waits in benchmarks/parts/freeform/jobs/ (issue #46), not here.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from conftest import run_camtool

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
JOBS = sorted(p.name for p in SAMPLES.glob("*.toml"))
XFAIL: dict[str, str] = {}

pytestmark = pytest.mark.samples


@pytest.fixture(autouse=True)
def _only_when_selected(request):
    if "samples" not in (request.config.getoption("markexpr") or ""):
        pytest.skip("a whole run per sample: select with -m samples")


def _freeform_refused(job: Path) -> str:
    """The refusal's text if this camtool does not take fit.model = "freeform" yet, else ''."""
    if 'model = "freeform"' not in job.read_text():
        return ""
    r = run_camtool("fit", job)
    text = r.stderr + r.stdout
    return text.strip() if r.returncode != 0 and "freeform" in text and "expected one of" in text else ""


def test_every_sample_is_tested():
    assert {"sphere.toml", "sia20_wall.toml", "sia20_paper_wall.toml", "freeform_hood.toml",
            "freeform_shell_scan.toml", *XFAIL} <= set(JOBS)


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=XFAIL[n]))
                                  if n in XFAIL else n for n in JOBS])
def test_sample_runs(name, tmp_path):
    job = SAMPLES / name
    refused = _freeform_refused(job)
    if refused:
        pytest.skip(f'fit.model = "freeform" not accepted yet: {refused.splitlines()[-1][:120]}')
    r = run_camtool("run", job, "-o", tmp_path / "out")
    assert r.returncode == 0, f"{name}: exit {r.returncode}\n{r.stderr[-2000:]}"
    strays = [line for line in r.stderr.splitlines() if line.strip() and not line.startswith("camtool:")]
    assert not strays, f"{name}: a line on stderr that is not camtool's own: {strays[:3]}"


def test_the_sia20_plate_runs_where_its_reach_hint_puts_it(tmp_path):
    """Issue #48: the plate job on the SIA20D (tests/jobs/sia20_plate.toml) is out of reach where the
    IRB2400 has it; the placement its reach hint prints runs end to end, its INFORM job accepted by
    the program simulator (the E axis held near the plan in straight moves, joint moves where the
    controller cannot follow a straight one past the wrist singularity)."""
    import re

    job = Path(__file__).resolve().parent / "jobs" / "sia20_plate.toml"
    r = run_camtool("run", job, "-o", tmp_path / "far")
    assert r.returncode == 3
    hint = re.search(r"(cell\.workpiece_xyz_mm = \[[^\]]+\])", r.stderr)
    assert hint, r.stderr[-500:]
    r = run_camtool("run", job, "--set", hint.group(1).replace(" ", ""), "-o", tmp_path / "out")
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stderr[-2000:]}"
    assert (tmp_path / "out" / "PLATE.JBI").is_file()


def test_the_shell_scan_program_keeps_within_the_aim_where_its_simulator_had_refused_it(tmp_path):
    """Issue #46: the shell scan at (1050, 100, 950) mm (tests/jobs/freeform_shell_scan_far.toml), where the
    corners of its RAPID program had cut the planned path by 0.255 mm (the scan's normals of then), runs end to
    end: the simulator, as strict as before, measures the program within post.path_tol_mm. (It came within the
    writer's aim, 0.8 of that, at 0.0799 mm until the free-form transitions ran from the straight leads' ends;
    since, 0.0915 mm, and writing its stretches closer does not lower it: 0.0976, 0.0986, so the first writing
    is placed. Issue #46's note says so.)"""
    import json

    job = Path(__file__).resolve().parent / "jobs" / "freeform_shell_scan_far.toml"
    r = run_camtool("run", job, "-o", tmp_path / "out")
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stderr[-2000:]}"
    sim = json.loads((tmp_path / "out" / "report.json").read_text())["programs_simulated"]["rapid"]
    assert sim["max_deviation_mm"] <= sim["path_tol_mm"]
    assert (tmp_path / "out" / "SHELL.mod").is_file()
