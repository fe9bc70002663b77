"""The house rules that keep the package readable: layers, short functions, docstrings, one public API.

The layer contract itself is import-linter's (pyproject.toml, ``[tool.importlinter]``); these tests run it, and
check what it cannot: function length, docstrings, citations of files the repository does not hold, the public
API of earlier releases, model files saved by them, and the code fingerprints that key caches and sweep cells.
"""
from __future__ import annotations

import ast
import io
import json
import re
import subprocess
import sys
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import roughsense
from roughsense._util.fingerprint import module_closure

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "src" / "roughsense"
MAX_FUNCTION_LINES = 60
LEGACY = Path(__file__).parent / "data" / "legacy_models"
EXAMPLE_STUDY = PACKAGE / "data" / "examples" / "my-study"


def _modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def test_the_layers_contract_holds():
    from importlinter.cli import lint_imports

    out = io.StringIO()
    with redirect_stdout(out):
        code = lint_imports(config_filename=str(REPO / "pyproject.toml"), no_cache=True, no_logo=True)
    assert code == 0, out.getvalue()[-3000:]


def test_sim_and_rig_never_import_the_analysis_and_the_analysis_never_imports_a_source():
    """The rule the layers exist for, checked on the closure of imports rather than on the contract's wording."""
    for source in ("roughsense.sim.simulate", "roughsense.rig.capture"):
        assert not [m for m in module_closure(source) if m.startswith(("roughsense.analysis", "roughsense.model"))]
    analysis = module_closure("roughsense.analysis.study_analysis")
    assert not [m for m in analysis if m.startswith(("roughsense.sim", "roughsense.rig"))]


def test_no_function_is_longer_than_sixty_lines():
    long = []
    for path in _modules():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{path.relative_to(REPO)}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, "\n".join(long)


def test_every_module_says_its_job_and_every_package_its_layer():
    missing, short_packages = [], []
    for path in _modules():
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        if not doc or not doc.strip().splitlines()[0].strip():
            missing.append(str(path.relative_to(REPO)))
        elif path.name == "__init__.py" and len(doc.strip().splitlines()) < 2:
            short_packages.append(str(path.relative_to(REPO)))
    assert not missing, f"modules without an opening docstring: {missing}"
    assert not short_packages, f"packages whose docstring does not say their layer's job in two lines: {short_packages}"


def _text_files() -> list[Path]:
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"], cwd=REPO,
                            capture_output=True, text=True, check=True).stdout.split()
    return [REPO / name for name in listed if name.endswith((".py", ".md", ".toml", ".txt")) and (REPO / name).is_file()]


def test_nothing_cites_a_design_file_the_repository_does_not_hold():
    brief = "DESIGN" + ".md"  # the team's brief lives outside the repository; docs/architecture.md is ours
    citing = [str(path.relative_to(REPO)) for path in _text_files()
              if brief in path.read_text(encoding="utf-8", errors="replace")]
    assert not citing, citing


_PACKAGE_FOLDERS = ("_util", "io", "sensor", "model", "analysis", "sim", "rig", "report", "explore", "cli", "data")
_CITED_PATH = re.compile(r"(?<![\w./-])((?:docs|src|tests|benchmarks|scripts|examples|" + "|".join(_PACKAGE_FOLDERS)
                         + r")/[\w./-]*\w\.(?:md|py|toml|csv|json))")


def test_every_file_path_a_text_cites_exists():
    """A cited path under docs, tests, src, or a package folder (sim, io, ...) exists: a move cannot leave one behind."""
    dangling = []
    for path in _text_files():
        if path.name == "CHANGELOG.md":  # a record of its day: it names the files of each issue, moved since or not
            continue
        for match in _CITED_PATH.finditer(path.read_text(encoding="utf-8", errors="replace")):
            cited = match.group(1)
            if not any((base / cited).exists() for base in (REPO, PACKAGE)):
                dangling.append(f"{path.relative_to(REPO)}: {cited}")
    assert not dangling, "\n".join(dangling)


def test_the_public_api_of_earlier_releases_still_imports():
    earlier = ["__version__", "RoughsenseError", "InputError", "ConfigError", "ModelFileError", "OutputExistsError",
               "SpatialSpectrum", "spatial_spectrum", "frequency_grid", "SIMPLS", "pls_cv", "pls_cv_many",
               "SpreadModel", "load_model", "overlap", "read_study", "StudyWriter", "simulate_study"]
    for name in [*earlier, "analyse_study"]:
        assert name in roughsense.__all__
        assert getattr(roughsense, name) is not None
    from roughsense.analysis.study_analysis import analyse_study

    assert roughsense.analyse_study is analyse_study and analyse_study.__doc__


@pytest.mark.parametrize("condition", ["2N", "combined"])
def test_model_files_saved_before_the_redesign_predict_the_same(condition):
    """Files written by roughsense 0.1.0 before the package moved (fit on the example my-study) score alike today."""
    from roughsense.io.study import read_study
    from roughsense.model.modelfile import load_model
    from roughsense.model.scoring import score_images
    from roughsense.model.trials import groups_from_study

    loaded = load_model(LEGACY / f"model_{condition}.json")
    groups, meta = groups_from_study(loaded, read_study(EXAMPLE_STUDY))
    scores = score_images(loaded, [image for trial in groups for image in trial])
    expected = pd.read_csv(LEGACY / f"predictions_{condition}.csv")
    assert list(meta["specimen"]) == list(expected["specimen"])
    np.testing.assert_allclose(scores, expected["roughness"].to_numpy(), rtol=1e-12, atol=0)
    document = json.loads((LEGACY / f"model_{condition}.json").read_text())
    assert document["roughsense_version"] == "0.1.0" and document["model"]["kind"] == "pls1-simpls"


def test_the_simulated_study_cache_covers_every_module_a_simulation_loads(tmp_path):
    """Run a small simulation in a fresh interpreter: every roughsense module it loaded is in the cache key."""
    script = (
        "import sys\n"
        "from roughsense.sim.optics import Camera\n"
        "from roughsense.sim.config import SimulationConfig\n"
        "from roughsense.sim.simulate import simulate_study\n"
        "config = SimulationConfig(pads=('smooth',), specimens=('R2',), forces_n=(1.0,), repetitions=1, seed=1,\n"
        "                          camera=Camera(width_px=400, height_px=300))\n"
        f"simulate_study({str(tmp_path / 's')!r}, config=config, jobs=1)\n"
        "print(' '.join(sorted(m for m in sys.modules if m.startswith('roughsense'))))\n"
    )
    loaded = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    from roughsense.cli._studies import SIMULATOR_DATA, SIMULATOR_ENTRY_POINTS

    covered = set(module_closure(*SIMULATOR_ENTRY_POINTS))
    data = {name.rsplit(".", i)[0] for name in SIMULATOR_DATA for i in range(name.count("."))}  # and their parents
    assert "roughsense.io.writer" in loaded and "roughsense.sim.contact" in loaded
    assert set(loaded) - covered - data == set()


def test_a_sweep_cell_fingerprint_covers_the_twin_and_the_analysis():
    from roughsense.explore.code_fingerprint import ENTRY_POINTS

    cell = set(module_closure(*ENTRY_POINTS))
    assert set(module_closure("roughsense.sim.simulate")) <= cell
    assert set(module_closure("roughsense.analysis.study_analysis")) <= cell
    assert {"roughsense.sensor.spectrum", "roughsense.model.pls.cv", "roughsense.paper"} <= cell
    assert not [m for m in cell if m.startswith(("roughsense.cli", "roughsense.report"))]  # presentation only


def test_a_fingerprint_changes_with_any_module_it_covers(tmp_path, monkeypatch):
    """Copy the package, change one byte of a module deep in the closure: the fingerprint moves."""
    import shutil

    from roughsense._util import fingerprint

    copy = tmp_path / "roughsense"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    entry = ("roughsense.sim.simulate",)
    monkeypatch.setattr(fingerprint, "PACKAGE_DIR", copy)
    before = fingerprint.code_fingerprint.__wrapped__(*entry)
    writer = copy / "io" / "writer.py"
    writer.write_text(writer.read_text() + "\n# changed\n")
    after = fingerprint.code_fingerprint.__wrapped__(*entry)
    assert before != after


#: The share of src modules a test imports by their own dotted path (issue 45: tests find their modules).
MIN_OWN_PATH_SHARE = 0.85


def _imported_by_own_path(module: str, text: str) -> bool:
    """``import roughsense.x.y``, ``from roughsense.x.y import ...`` or ``from roughsense.x import y``."""
    parent, _, leaf = module.rpartition(".")
    return bool(re.search(rf"\b(?:import|from)\s+{re.escape(module)}\b", text) or re.search(
        rf"\bfrom\s+{re.escape(parent)}\s+import\s+(?:\([^)]*\b{leaf}\b|[^\n]*\b{leaf}\b)", text))


def test_most_modules_are_imported_by_their_own_path_in_a_test():
    """A test that reaches a module through a re-export, or only through the CLI, leaves it unfound: its tests are
    not beside its path. At least 85 % of the modules (``__init__`` aside) must be imported by their own path."""
    modules = [".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts) for path in _modules()
               if path.name != "__init__.py"]
    text = "\n".join(path.read_text(encoding="utf-8") for path in Path(__file__).parent.rglob("*.py"))
    missing = [module for module in modules if not _imported_by_own_path(module, text)]
    share = 1 - len(missing) / len(modules)
    assert share >= MIN_OWN_PATH_SHARE, f"{share:.1%} of {len(modules)} modules; not imported by their own path: " \
                                        + ", ".join(missing)


def _import_graph() -> dict[str, set[str]]:
    """Each module's direct imports of roughsense modules, ``if TYPE_CHECKING:`` blocks and function bodies included:
    a loop only a type annotation closes is still two modules that cannot be read one before the other."""
    modules = {".".join(("roughsense", *p.relative_to(PACKAGE).with_suffix("").parts)).removesuffix(".__init__"): p
               for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                edges.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
                target = ".".join([*base, *([node.module] if node.module else [])])
                edges.update(f"{target}.{a.name}" if f"{target}.{a.name}" in modules else target for a in node.names)
        graph[name] = {e for e in edges if e in modules and e != name}
    return graph


def _loops(graph: dict[str, set[str]]) -> list[set[str]]:
    """The import graph's strongly connected components of more than one module (each is a loop)."""
    reach = {m: set() for m in graph}
    for start in graph:
        todo = list(graph[start])
        while todo:
            m = todo.pop()
            if m not in reach[start]:
                reach[start].add(m)
                todo.extend(graph[m])
    loops = []
    for m in graph:
        component = {m} | {other for other in reach[m] if m in reach[other]}
        if len(component) > 1 and component not in loops:
            loops.append(component)
    return loops


def test_no_import_loop_outside_the_model_layer():
    """sim/config and sim/plan imported each other (plan only for a type); io/sensor_settings and io/study_config did
    too. model/'s own loops are being untangled as its families move into packages."""
    graph = _import_graph()
    assert "roughsense.sim.plan" in graph["roughsense.sim.frames"]  # the graph sees relative imports
    assert _loops({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
    outside = [loop for loop in _loops(graph) if not all(m.startswith("roughsense.model.") for m in loop)]
    assert outside == []
