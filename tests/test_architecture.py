"""The house by stage (issue #45): the layers in order, imports that run one way, few modules at the top,
and the raw job read only in the run wing (and the drivers above it)."""
import ast
from pathlib import Path

from test_imports import import_graph

ROOT = Path(__file__).resolve().parents[1]

# Top to bottom. A module may import its own layer or any layer below it, never one above. A module
# belongs to the layer of its longest matching prefix (``camtool.program.post`` is not ``camtool.program``).
LAYERS = (
    ("camtool.cli", "camtool.commands"),                                  # the command line
    ("camtool.batch", "camtool.design", "camtool.placement.search"),      # drivers: many runs of a job
    ("camtool.run",),                                                     # the pipeline, stages, tasks, job read once
    ("camtool.placement",),                                               # reach screens, margins, shifts
    ("camtool.report",),                                                  # report.json, report.html, figures
    ("camtool.program.post",),                                            # the post stage: write, check, simulate
    ("camtool.simulate",),                                                # the controller's interpolation
    ("camtool.program", "camtool.process"),                               # program model; what the tool does
    ("camtool.motion",),                                                  # the independent motion check
    ("camtool.plan",),                                                    # redundant planning
    ("camtool.timing",),                                                  # timing and its 4 ms check
    ("camtool.trajectory",),                                              # JointPath, Trajectory
    ("camtool.path",),                                                    # rasters on a surface, the Path box
    ("camtool.collision",),                                               # the cell's collision world
    ("camtool.part",),                                                    # workpieces, fits, faces, surfaces
    ("camtool.settings", "camtool.job"),                                  # job file and per-stage settings
    ("camtool.robots",),                                                  # robot models
    ("camtool.collision.spec", "camtool.alongside", "camtool.transforms", "camtool.safe_io", "camtool.files",
     "camtool.vary", "camtool.console", "camtool.errors", "camtool"),    # plain utilities
)
MAX_TOP_LEVEL_MODULES = 12


def layer_of(module: str) -> int | None:
    best = None
    for i, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and (best is None or len(p) > len(best[1])):
                best = (i, p)
    return None if best is None else best[0]


def upward_imports(graph) -> list[tuple[str, str]]:
    return [(m, t) for m, ts in sorted(graph.items()) if m.startswith("camtool")
            for t in sorted(ts) if t.startswith("camtool") and layer_of(t) < layer_of(m)]


def test_every_camtool_module_has_a_layer():
    assert not [m for m in import_graph() if m.startswith("camtool") and layer_of(m) is None]


def test_no_import_runs_upwards():
    found = upward_imports(import_graph())
    assert not found, "upward imports: " + "; ".join(f"{m} -> {t}" for m, t in found)


def test_an_upward_import_is_found():
    graph = {"camtool.part.fit": {"camtool.run.stages"}, "camtool.run.stages": {"camtool.part.fit"}}
    assert upward_imports(graph) == [("camtool.part.fit", "camtool.run.stages")]


def test_few_modules_stand_at_the_top():
    top = sorted(f.name for f in (ROOT / "camtool").glob("*.py"))
    assert len(top) <= MAX_TOP_LEVEL_MODULES, top


def _takes_a_job(file: Path, root: Path = ROOT) -> list[str]:
    """Functions of ``file`` with a parameter annotated ``Job``, and imports of ``camtool.job.Job``."""
    tree = ast.parse(file.read_text())
    hits = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").endswith("job") and \
                any(a.name == "Job" for a in node.names):
            hits.append(f"{file.relative_to(root)}:{node.lineno} imports Job")
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for a in node.args.args + node.args.kwonlyargs:
                if a.annotation is not None and "Job" in ast.unparse(a.annotation).replace("JobSettings", "") \
                        .replace("JobPart", ""):
                    hits.append(f"{file.relative_to(root)}:{node.lineno} {node.name}({a.arg}: Job)")
    return hits


def test_below_the_run_wing_nothing_takes_the_raw_job():
    """The job is read once at the top (``camtool.run``: ``JobSettings.from_job``, ``post_inputs``,
    ``part_stages.faces_settings``); the stages below take settings objects."""
    run = layer_of("camtool.run")
    below = [f for f in (ROOT / "camtool").rglob("*.py")
             if (m := ".".join(f.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"))
             and layer_of(m) > run and m not in ("camtool.job", "camtool.settings")]
    hits = [h for f in below for h in _takes_a_job(f)]
    assert not hits, hits


def test_the_job_check_sees_a_job_parameter(tmp_path):
    f = tmp_path / "stage.py"
    f.write_text("from ..job import Job\n\ndef stage(job: Job, settings: JobSettings):\n    pass\n")
    assert len(_takes_a_job(f, tmp_path)) == 2


MAX_FUNCTION_LINES = 80


def long_functions(root: Path = ROOT) -> list[str]:
    """Functions over MAX_FUNCTION_LINES lines in camtool/ and postprocessors/, but click commands (argument
    parsing) and numba kernels (one compiled loop), which issue #45 leaves whole."""
    found = []
    for pkg in ("camtool", "postprocessors"):
        for f in sorted((root / pkg).rglob("*.py")):
            for node in ast.walk(ast.parse(f.read_text())):
                if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    continue
                decorators = " ".join(ast.unparse(d) for d in node.decorator_list)
                if "click." in decorators or "njit" in decorators or "numba" in decorators:
                    continue
                if node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES:
                    found.append(f"{f.relative_to(root)}:{node.lineno} {node.name}")
    return found


def test_no_function_hides_its_steps_in_over_80_lines():
    assert not long_functions()


def test_a_long_function_is_found(tmp_path):
    (tmp_path / "camtool").mkdir()
    (tmp_path / "postprocessors").mkdir()
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))
    (tmp_path / "camtool" / "long.py").write_text(f"def long():\n{body}")
    assert long_functions(tmp_path) == ["camtool/long.py:1 long"]
