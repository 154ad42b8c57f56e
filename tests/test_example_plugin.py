"""The example third-party plugin (examples/urscript_post): written against the documented
base only, it registers, writes through write_programs, and is checked by reading back."""
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import camtool.program.registry as registry
from camtool.errors import PlanInfeasible
from camtool.program.post import ResolvedPost, write_programs
from camtool.program.profiles import defaults_profile
from camtool.robots import get_robot
from camtool.settings import PostSettings
from post_fixtures import smooth_trajectory

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "urscript_post"))
from camtool_urscript import UrScriptPost  # noqa: E402


@pytest.fixture
def registered(monkeypatch):
    ep = SimpleNamespace(name="urscript", value="camtool_urscript:UrScriptPost",
                         dist=SimpleNamespace(name="camtool-urscript"), load=lambda: UrScriptPost)
    monkeypatch.setattr(registry, "entry_points", lambda **kw: [ep])
    registry.clear_cache()
    yield registry.get_plugin("urscript")
    registry.clear_cache()


def _post(plugin, r, formats=("urscript",)):
    settings = PostSettings.make(formats=list(formats), program_name="Demo")
    profile = defaults_profile("urscript", r.name, plugin).with_changes(program_name="Demo")
    return settings, {"urscript": ResolvedPost("urscript", plugin, profile)}


def test_the_example_registers_and_describes_itself(registered):
    assert isinstance(registered, UrScriptPost)
    row = next(r for r in registry.describe_plugins() if r["name"] == "urscript")
    assert row["source"] == "camtool-urscript" and row["check"] == "read-back" and not row["simulated"]


def test_the_example_writes_and_is_checked_by_reading_back(registered, tmp_path):
    r = get_robot("irb2400")
    tr = smooth_trajectory(r, 20)
    settings, profiles = _post(registered, r)
    files = write_programs(tr, r, settings, profiles, tmp_path / "o")
    assert [f.name for f in files] == ["Demo.script"]
    dur, q = registered.read(files[0], r, profiles["urscript"].profile)
    assert np.allclose(q, tr.q, atol=1e-6) and np.allclose(dur[1:], np.diff(tr.t_s), atol=1e-4)


def test_a_broken_example_program_is_not_placed(registered, tmp_path, monkeypatch):
    r = get_robot("irb2400")
    real = UrScriptPost.write

    def spoiled(self, trajectory, robot, profile, outdir, process):
        files = real(self, trajectory, robot, profile, outdir, process)
        files[0].write_text(files[0].read_text().replace("t=", "t=-", 3))
        return files
    monkeypatch.setattr(UrScriptPost, "write", spoiled)
    settings, profiles = _post(registered, r)
    with pytest.raises(PlanInfeasible):
        write_programs(smooth_trajectory(r, 20), r, settings, profiles, tmp_path / "o")
    assert not (tmp_path / "o" / "Demo.script").exists()
