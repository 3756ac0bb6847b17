"""Every table of README.md and docs/*.md names where it comes from, and every command named
runs and prints its tables (issue 18 item 1). The registry and the rules:
training/bench/doc_tables.py.

The small forms that train a model (10–30 s of CPU each) run only with IMUFMU_DOC_TABLES_TRAIN=1,
so that this file stays within about a minute of CPU by default; the others always run.
"""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from training.bench.doc_tables import (GENERATORS, PENDING_DOCS, ROOT, SHARED, DocTable, coverage_problems,
                                       normalised_header, source_problem, tables)

#: Opt-in for the small forms that train a model.
TRAIN_ENV = "IMUFMU_DOC_TABLES_TRAIN"
#: A small form that runs longer than this [s] is no longer small.
SMALL_TIMEOUT_S = 300


def test_every_doc_table_names_its_source():
    assert coverage_problems() == []


def test_pending_docs_are_named_in_the_registry():
    # The lead empties PENDING_DOCS at merge; until then each still exists and is skipped by name.
    assert all((ROOT / doc).is_file() for doc in PENDING_DOCS)


def _table(doc: str) -> DocTable:
    (table,) = tables("x.md", doc)
    return table


SPEED = next(g for g in GENERATORS if g.command.startswith("imufmu bench speed"))


@pytest.mark.parametrize("doc, problem", [
    ("Some text.\n\n| a | b |\n|---|---|\n| 1 | 2 |\n", "names no source"),
    ("Command: `python benchmarks/nowhere.py`\n\n| a | b |\n|---|---|\n", "not in training/bench/doc_tables.py"),
    (f"Command: `{SPEED.command}`\n\n| a | b |\n|---|---|\n", "header is not one that"),
    ("<!-- hand-written:  -->\n| a | b |\n|---|---|\n", "names no source"),
])
def test_a_table_without_its_source_is_reported(doc, problem):
    assert problem in source_problem(_table(doc))


@pytest.mark.parametrize("doc", [
    "<!-- hand-written: a table of rules -->\n| a | b |\n|---|---|\n",
    f"Command: `{SPEED.command}`\n\n{SPEED.headers[1]}\n|---|---|---|\n",
    f"{SPEED.headers[1]}\n|---|---|---|\n\nCommand: `{SPEED.command}`\n",
    "<!-- generated:begin x (python -m contract.generate, from contract/variables.py) -->\n| a |\n|---|\n",
])
def test_a_table_with_its_source_passes(doc):
    assert source_problem(_table(doc)) is None


def test_tables_in_code_fences_are_not_tables():
    assert tables("x.md", "```\n| a | b |\n```\n") == []


def test_every_generator_has_a_small_form_or_says_why_not():
    for g in GENERATORS:
        assert (g.small is None) != (g.why_not_small == ""), g.command
        assert g.headers or g.why_not_small.startswith("pending"), g.command


def _small_cases():
    for g in GENERATORS:
        if g.small is not None:
            marks = [pytest.mark.skipif(g.trains and os.environ.get(TRAIN_ENV) == "0",
                                        reason=f"trains a model: {TRAIN_ENV}=0 skips it")]
            yield pytest.param(g, id=g.command.split("--out")[0].replace("OMP_NUM_THREADS=1 ", "").strip(),
                               marks=marks)


@pytest.mark.parametrize("generator", list(_small_cases()))
def test_generator_prints_its_tables_on_its_small_input(generator, tmp_path):
    missing = [n for n in generator.needs if not (SHARED / n).exists()]
    if missing:
        pytest.skip(f"shared data missing: {', '.join(str(SHARED / n) for n in missing)}")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in generator.small]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    run = subprocess.run([sys.executable, *argv], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=SMALL_TIMEOUT_S)
    assert run.returncode == 0, run.stderr[-2000:]
    printed = {normalised_header(line) for line in run.stdout.splitlines() if line.startswith("|")}
    for header in generator.headers:
        assert normalised_header(header) in printed, f"{generator.command}: no table {header!r} in its output"
