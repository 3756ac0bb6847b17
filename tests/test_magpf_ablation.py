"""The mode-0 ablation table of docs/magpf.md (benchmarks/magpf_ablation.py) on a small input."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

import magpf_ablation  # noqa: E402
from training.models import magpf  # noqa: E402

# Small input: 2 seeds of 10 s (the docs' table: 20 seeds of 60 s).
SEEDS = 2
SECONDS = 10.0


def test_ablation_table_has_the_source_method_each_addition_and_the_baselines(capsys):
    assert magpf_ablation.main(["--seeds", str(SEEDS), "--seconds", str(SECONDS)]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    labels = [line.split(" | ")[0][2:] for line in lines[1:]]
    additions = magpf.ADDITIONS + magpf.LATER_ADDITIONS
    assert labels[0] == magpf_ablation.SOURCE_LABEL
    suffix = magpf_ablation.WITH_ADDITIONS_SUFFIX
    assert [label.removesuffix(suffix) for label in labels[1:1 + len(additions)]] == [f"+ {a.label}" for a in additions]
    assert [label.endswith(suffix) for label in labels].index(True) == len(magpf.ADDITIONS)
    assert labels[-2:] == [magpf_ablation.RB_LABEL, magpf_ablation.ELLIPSOID_LABEL]
    assert len(labels) == len(set(labels)) == 1 + len(additions) + 2 + 2
    for line in lines[1:]:   # 4 cells "mean / worst", finite, mean <= worst; then the declared changes
        cells = line.strip("| ").split(" | ")[1:]
        figures = [[float(v) for v in cell.split(" / ")] for cell in cells[:4]]
        assert len(cells) == 5 and all(np.isfinite(m) and m <= w for m, w in figures)
        assert cells[4] == "—" if line.startswith(f"| {magpf_ablation.ELLIPSOID_LABEL} |") else (
            all(0 <= int(k) <= SEEDS for k in cells[4].split(" / ")))


def test_the_source_method_is_not_the_method_with_additions():
    # the pure row must run a different filter: its figures differ from the additions' row on
    # every scenario, and its settings switch every addition off
    result = magpf_ablation.ablation(SEEDS, SECONDS)
    rows = magpf_ablation.variants()
    with_additions = next(label for label, s in rows.items() if s == magpf.METHOD_WITH_ADDITIONS)
    for scenario in ("tumbling", "jump"):
        assert not np.array_equal(result[magpf_ablation.SOURCE_LABEL][scenario], result[with_additions][scenario])
    for addition in magpf.ADDITIONS + magpf.LATER_ADDITIONS:
        assert all(magpf.SOURCE_METHOD[k] == v for k, v in addition.off.items())
        assert addition.on != addition.off


def test_source_sweep_table_varies_only_the_methods_own_parameters(capsys):
    assert magpf_ablation.main(["--seeds", "1", "--seconds", str(SECONDS), "--source-sweep"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    assert [line.split(" | ")[0][2:] for line in lines[1:]] == list(magpf_ablation.SOURCE_SWEEP)
    additions = {k for a in magpf.ADDITIONS + magpf.LATER_ADDITIONS for k in a.off}
    for s in magpf_ablation.source_sweep().values():
        assert all(s[k] == magpf.SOURCE_METHOD[k] for k in additions)
