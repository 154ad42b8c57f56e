"""Same job, same bytes (issue #48): no stage of a run counts seconds to decide anything, so a job run beside a
busy loop writes the same programs as one run alone. On the SIA20 wall (samples/sia20_wall.toml), whose plan
an earlier report found "depends on machine load"."""
import subprocess
import sys

import pytest

from conftest import SAMPLES, run_camtool

pytestmark = pytest.mark.samples  # two whole runs (minutes): with the samples, `make samples`


def test_the_sia20_wall_writes_the_same_program_under_load(tmp_path):
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        loaded = subprocess.Popen([sys.executable, "-m", "camtool.cli", "run", str(SAMPLES / "sia20_wall.toml"),
                                   "-o", str(tmp_path / "loaded"), "-q"], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        alone = run_camtool("run", SAMPLES / "sia20_wall.toml", "-o", tmp_path / "alone", "-q")
        out, err = loaded.communicate()
    finally:
        busy.kill()
        busy.wait()
    assert alone.returncode == 0, alone.stderr
    assert loaded.returncode == 0, err
    a, b = (tmp_path / "alone" / "SIAWALL.JBI").read_bytes(), (tmp_path / "loaded" / "SIAWALL.JBI").read_bytes()
    assert a == b
    assert (tmp_path / "alone" / "points.csv").read_bytes() == (tmp_path / "loaded" / "points.csv").read_bytes()
