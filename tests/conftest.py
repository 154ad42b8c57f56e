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
