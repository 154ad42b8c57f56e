"""The program wing's layers (issue #22): core never imports a plugin package, plugins never
import the simulator, and nothing probes a plugin for optional capabilities."""
import re
from pathlib import Path

from test_imports import import_graph

ROOT = Path(__file__).resolve().parents[1]


def test_no_camtool_module_imports_a_plugin_package():
    """The built-ins are named as strings in camtool.program.registry and imported on use; the batch
    cache finds their folder (importlib's find_spec) to hash it without importing it."""
    graph = import_graph()
    up = {m: sorted(t for t in ts if t.startswith("postprocessors")) for m, ts in graph.items()
          if m.startswith("camtool")}
    assert not {m: t for m, t in up.items() if t}


def test_no_plugin_imports_the_simulator():
    graph = import_graph()
    found = {m: sorted(t for t in ts if t.startswith("camtool.simulate")) for m, ts in graph.items()
             if m.startswith("postprocessors")}
    assert not {m: t for m, t in found.items() if t}


def test_the_program_model_imports_no_simulator():
    """The post stage (``camtool.program.post``) reads the written programs back through the
    simulator; the program model it writes from never imports it."""
    graph = import_graph()
    assert not {m for m, ts in graph.items() if m.startswith("camtool.program") and m != "camtool.program.post"
                and any(t.startswith("camtool.simulate") for t in ts)}


def test_no_capability_probes_of_plugins():
    """camtool asks a plugin only what ``PostProcessor`` declares: no hasattr / getattr /
    inspect.signature on plugin objects in the post stage, the registry or the commands."""
    files = [*(ROOT / "camtool" / "program").glob("*.py"),
             *(ROOT / "camtool" / "commands").glob("*.py"), *(ROOT / "postprocessors").rglob("*.py")]
    probe = re.compile(r"\b(hasattr|getattr)\(\s*(plugin|p|info\.plugin|self)\b|inspect\.signature")
    hits = [f"{f.relative_to(ROOT)}:{n}" for f in files for n, line in enumerate(f.read_text().splitlines(), 1)
            if probe.search(line)]
    assert not hits


def test_write_programs_takes_no_job():
    import inspect

    from camtool.program.post import write_programs

    params = list(inspect.signature(write_programs).parameters)
    assert params[:5] == ["trajectory", "robot", "post_settings", "profiles", "outdir"]
    assert "job" not in params
