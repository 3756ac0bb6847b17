"""`imufmu bench methods` (issue 33 item 1): one row per form of every source method, each through the FMU, the runtime
forms really switched, and a method that cannot run on the data reported in its row instead of a crash.

One bench run on a short simulated calibration without temperature (139 s at 50 Hz, the last quarter held out): the
PSO-BP network cannot be fitted there, so the run trains only train's own model and the ELM's two forms (~20 s)."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from contract import layout
from training.bench.methods_bench import FIGURES, OWN, TABLE_HEADER, _figures, product_form
from training.data.reference_source import strip_references
from training.cli import main
from training.data.io import write_imu_csv
from training.main_job import SCENARIO_DIR
from training.models.methods import METHODS
from training.simulator import load_scenario, simulate


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """(methods.json as a dict, methods.md's text, the session) of one bench run on a session without temperature."""
    tmp = tmp_path_factory.mktemp("bench_methods")
    data = simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_calibration_clean.toml"))
    data = replace(data, temp=np.full(len(data), np.nan))
    path = write_imu_csv(data, tmp / "session.csv.gz")
    assert main(["bench", "methods", str(path), "--out", str(tmp / "out")]) == 0
    return json.loads((tmp / "out" / "methods.json").read_text()), (tmp / "out" / "methods.md").read_text(), data


def _rows(doc: dict) -> dict[tuple[str, str], dict]:
    """(method, form) -> row of methods.json."""
    return {(r["method"], r["form"]): r for r in doc["rows"]}


def test_every_method_form_has_a_row_and_a_line_of_the_table(bench):
    doc, text, _ = bench
    forms = [(m, f) for m, fs in METHODS.items() for f in fs]
    rows = _rows(doc)
    assert set(forms) <= set(rows)
    assert [m for m, f in rows if f.startswith(OWN)] == list(METHODS)
    lines = text.splitlines()
    table = lines[lines.index(TABLE_HEADER):]
    assert len([line for line in table if line.startswith("| `")]) == len(doc["rows"])
    assert "NO --eval RECORDING" in doc["split"]


def test_the_runtime_forms_are_switched_in_the_fmu(bench):
    rows = _rows(bench[0])
    for method, forms in (("attitude", ("source-euler", "quaternion")), ("pf", ("source", "rb"))):
        a, b = (rows[(method, form)] for form in forms)
        assert a["referenced"] and b["referenced"]
        assert not np.allclose(a["values"], b["values"], rtol=1e-3), (method, a["values"], b["values"])
    assert rows[("attitude", "quaternion")]["product"] and not rows[("attitude", "source-euler")]["product"]


def test_the_elm_forms_are_trained_by_train_method(bench):
    rows = _rows(bench[0])
    source, product = rows[("elm", "source")], rows[("elm", "product")]
    assert source["how"] == "`train --method elm=source`" and not source["cannot_run"]
    assert source["values"] != product["values"]


def test_without_temperature_the_psobp_rows_say_why_instead_of_crashing(bench):
    rows = _rows(bench[0])
    for form in METHODS["psobp"]:
        assert "temperature" in rows[("psobp", form)]["cannot_run"]
        assert rows[("psobp", form)]["values"] is None


def test_without_a_reference_a_row_shows_its_difference_from_the_product(bench):
    data = bench[2].slice(slice(0, 100))
    product = np.zeros((100, len(layout.OUTPUTS)))
    product[:, layout.OUTPUTS.index("q_w")] = 1.0  # level, north
    out = product.copy()
    out[:, layout.OUTPUTS.index("roll")] = np.deg2rad(0.5)
    settings = dict(layout.SETTINGS)
    values, referenced = _figures(FIGURES["attitude"], [out], [product], [strip_references(data)], settings)
    assert not referenced and np.allclose(values, [0.5, 0.0, 0.0])
    assert _figures(FIGURES["attitude"], [out], [product], [data], settings)[1]


def test_the_product_forms_and_figures_cover_every_method():
    assert set(FIGURES) == set(METHODS)
    assert {m: product_form(m) for m in METHODS} == {"elm": "product", "pf": "rb", "psobp": "product",
                                                     "attitude": "quaternion"}


def test_bad_input_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,gyr_x\n0,1\n")
    assert main(["bench", "methods", str(bad), "--out", str(tmp_path / "o")]) == 1
    assert main(["bench", "methods", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("imufmu bench: error: ") for line in err)
    assert "not found" in err[1]
