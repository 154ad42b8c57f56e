"""Shared test helpers: run the CLI in-process or as a subprocess."""
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"


@pytest.fixture
def cli():
    """Invoke camtool in-process: cli(args...) -> click Result (exit_code, output, stderr)."""
    from camtool.cli import cli as group

    runner = CliRunner()

    def invoke(*args):
        return runner.invoke(group, [str(a) for a in args], catch_exceptions=False)

    return invoke


def run_camtool(*args, cwd=None, env=None):
    """Run camtool as a separate process (as a user would)."""
    return subprocess.run([sys.executable, "-m", "camtool.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, env=env)


# The files with the longest runs (full jobs end to end), in the order `make test`'s two workers
# should start them: the longest first, so the short files fill the gaps at the end.
LONGEST_FIRST = ("test_cli_batch.py", "test_pipeline.py", "test_faces.py", "test_cell_samples.py",
                 "test_safe_motion.py", "test_cli_place.py", "test_bad_input_corpus.py", "test_step.py",
                 "test_arm_angle_sqp.py", "test_output.py", "test_cli_stages.py", "test_connectors.py",
                 "test_controller_truth.py", "test_cli_check.py")


def pytest_collection_modifyitems(config, items):
    """Longest files first (a stable sort: the order within a file is kept). Tests marked ``samples`` (whole
    runs of shipped jobs: `make samples`, which CI runs after `make test`) skip unless selected with -m samples."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(Path(str(item.fspath)).name, len(rank)))
    if "samples" not in (config.getoption("markexpr") or ""):
        skip = pytest.mark.skip(reason="a whole run of a shipped job: select with -m samples (make samples)")
        for item in items:
            if item.get_closest_marker("samples"):
                item.add_marker(skip)
