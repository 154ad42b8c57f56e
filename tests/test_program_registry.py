"""The post-processor registry (issue #28 item 5): built-ins always win a name clash, a
plugin's import failure of any kind is caught per plugin, --no-plugins and CAMTOOL_PLUGINS."""
import json
from types import SimpleNamespace

import pytest
from click.testing import CliRunner

import camtool.program.registry as registry
from camtool.cli import cli
from camtool.program.plugin import PostProcessor


class _Txt(PostProcessor):
    name = "txt"
    extension = ".txt"
    requires_profile = False

    def write(self, trajectory, robot, profile, outdir, process):
        return []

    def read(self, path, robot, profile):
        return [], []


class _EvilRapid(_Txt):
    name = "rapid"


def _raise(exc):
    def load():
        raise exc
    return load


def _ep(name, load, dist="third-party"):
    return SimpleNamespace(name=name, value=f"{dist.replace('-', '_')}:{name}", dist=SimpleNamespace(name=dist),
                           load=load)


@pytest.fixture
def fake_entry_points(monkeypatch):
    """Install fake entry points; the registry is rebuilt for the test and after it."""
    def install(*eps):
        monkeypatch.setattr(registry, "entry_points", lambda **kw: list(eps))
        registry.clear_cache()
    yield install
    registry.clear_cache()


def test_a_plugin_cannot_replace_a_builtin(fake_entry_points):
    fake_entry_points(_ep("rapid", lambda: _EvilRapid), _ep("txt", lambda: _Txt))
    assert type(registry.get_plugin("rapid")).__module__ == "postprocessors.rapid"
    assert registry.discover()["txt"].plugin.name == "txt"
    clash = registry.clashes()
    assert len(clash) == 1 and clash[0].source == "third-party" and "built-in" in clash[0].error


def test_posts_lists_the_clash_as_an_error_and_exits_2(fake_entry_points):
    fake_entry_points(_ep("rapid", lambda: _EvilRapid))
    res = CliRunner().invoke(cli, ["posts"])
    assert res.exit_code == 2
    assert "ERROR rapid@third-party" in res.output and "always wins" in res.output
    res = CliRunner().invoke(cli, ["posts", "--json"])
    rows = {r["name"]: r for r in json.loads(res.stdout)}
    assert rows["rapid"]["builtin"] and rows["rapid@third-party"]["clash"]


def test_camtool_s_own_stale_entry_points_are_no_clash(fake_entry_points):
    fake_entry_points(_ep("rapid", lambda: _EvilRapid, dist="camtool"))
    assert registry.clashes() == [] and registry.discover()["rapid"].builtin


@pytest.mark.parametrize("exc", [SystemExit(7), KeyboardInterrupt(), ImportError("no numpy 3"), RuntimeError("x")])
def test_a_plugin_that_fails_to_import_breaks_only_itself(fake_entry_points, exc):
    fake_entry_points(_ep("broken", _raise(exc)), _ep("txt", lambda: _Txt))
    found = registry.discover()
    assert found["broken"].plugin is None and type(exc).__name__ in found["broken"].error
    assert found["txt"].plugin is not None and found["rapid"].plugin is not None
    res = CliRunner().invoke(cli, ["posts"])
    assert res.exit_code == 0 and "broken" in res.output and "FAILED TO LOAD" in res.output
    res = CliRunner().invoke(cli, ["check", "/nonexistent.mod", "--robot", "seed8"])
    assert res.exit_code == 2 and "program file not found" in res.output


def test_a_plugin_not_derived_from_the_base_is_refused(fake_entry_points):
    class Loose:
        name, extension, options_schema = "loose", ".x", {}
    fake_entry_points(_ep("loose", lambda: Loose))
    assert "does not derive from" in registry.discover()["loose"].error


def test_no_plugins_loads_only_the_builtins(fake_entry_points, monkeypatch):
    monkeypatch.setenv(registry.OFF_ENV, "0")  # restored (unset) after the test, whatever --no-plugins sets
    fake_entry_points(_ep("txt", lambda: _Txt))
    assert "txt" in registry.discover()
    res = CliRunner().invoke(cli, ["--no-plugins", "posts", "--json"])
    assert res.exit_code == 0
    assert {r["name"] for r in json.loads(res.stdout)} == {"rapid", "inform", "csv", "krl", "fanuc"}
    assert registry.os.environ[registry.OFF_ENV] == "1"  # for child processes (batch) too


def test_the_allow_list_loads_only_the_plugins_it_names(fake_entry_points, monkeypatch):
    fake_entry_points(_ep("txt", lambda: _Txt), _ep("broken", _raise(SystemExit(3))))
    monkeypatch.setenv(registry.ALLOW_ENV, "third-party:txt")  # a distribution and its entry point (#49)
    registry.clear_cache()
    assert set(registry.discover()) == {"rapid", "inform", "csv", "krl", "fanuc", "txt"}
    monkeypatch.setenv(registry.ALLOW_ENV, "")
    registry.clear_cache()
    assert set(registry.discover()) == {"rapid", "inform", "csv", "krl", "fanuc"}
