"""The import rules of docs/architecture.md on the graph that tools/import_graph.py reads with
`ast` (every import, absolute or relative, at the top of a file or inside a function):

- no cycle between modules;
- contract/ imports nothing of ours, fmu/ nothing from training/;
- in training/, a module imports only from its own layer or the layers below (LAYERS);
- training/ has at most MAX_TOP_LEVEL modules at its top level, the rest in subpackages.

`python tools/import_graph.py` prints the graph and its cycles for humans.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_SPEC = importlib.util.spec_from_file_location("import_graph", ROOT / "tools" / "import_graph.py")
import_graph = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(import_graph)

#: The layers of training/, bottom first: a module may import its own layer and the ones below.
#: Each entry names modules or subpackages (a prefix covers the package and everything in it).
LAYERS = (
    ("training.frames", "training.display", "training.runtime"),  # conventions, the C bridge
    ("training.data",),                                         # recordings and references
    ("training.simulator",),                                    # simulated recordings
    ("training.models", "training.selfcal", "training.noise"),  # models, twins, self-calibration, noise
    ("training.artefact", "training.evaluate", "training.mounting", "training.recommend",
     "training.completeness", "training.train", "training.fmu_build", "training.reports", "training.main_job",
     "training.attitude"),  # workflows
    ("training.diagnosis", "training.bench", "training.fleet", "training.sensor"),  # diagnosis, benchmarks, fleets,
                                                                                 # the virtual sensor
    ("training.cli",),                                          # the command line
)
#: The issue-17 bound on modules directly in training/ (its __init__.py not counted).
MAX_TOP_LEVEL = 12


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph.import_graph()


def _in(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def layer_of(module: str) -> int:
    """Index in LAYERS of a training module; KeyError when no layer declares it."""
    for k, layer in enumerate(LAYERS):
        if any(_in(module, prefix) for prefix in layer):
            return k
    raise KeyError(f"{module} is in no layer of tests/test_imports.py LAYERS")


def test_no_import_cycle(graph):
    assert import_graph.cycles(graph) == []


def test_the_cycle_finder_names_a_cycle_through_a_function_level_import(tmp_path):
    """Two modules that import each other, one of them only inside a function and relatively."""
    package = tmp_path / "training"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from training.b import g\n")
    (package / "b.py").write_text("def g():\n    from .a import f\n")
    found = import_graph.cycles(import_graph.import_graph(tmp_path, ("training",)))
    assert found == [["training.a", "training.b", "training.a"]]


def test_contract_imports_nothing_of_ours(graph):
    bad = {m: sorted(i for i in imports if not _in(i, "contract"))
           for m, imports in graph.items() if _in(m, "contract")}
    assert {m: i for m, i in bad.items() if i} == {}


def test_fmu_imports_nothing_from_training(graph):
    bad = {m: sorted(i for i in imports if _in(i, "training"))
           for m, imports in graph.items() if _in(m, "fmu")}
    assert {m: i for m, i in bad.items() if i} == {}


def test_every_training_module_has_a_layer(graph):
    unplaced = [m for m in graph if _in(m, "training") and m != "training"]
    for module in unplaced:
        layer_of(module)


def test_training_imports_point_down(graph):
    upward = [f"{m} (layer {layer_of(m)}) -> {i} (layer {layer_of(i)})"
              for m, imports in sorted(graph.items()) if _in(m, "training") and m != "training"
              for i in sorted(imports) if _in(i, "training") and layer_of(i) > layer_of(m)]
    assert upward == []


def test_training_top_level_is_small():
    modules = sorted(p.stem for p in (ROOT / "training").glob("*.py") if p.stem != "__init__")
    assert len(modules) <= MAX_TOP_LEVEL, modules
