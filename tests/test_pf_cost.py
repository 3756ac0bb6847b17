"""benchmarks/pf_cost.py (docs/magpf.md, *Cost*): its whole machinery — FMU built by the project's
builder, the C host co-simulating it through dlopen, VQF in the same run — on three seconds of a
simulated hand-held recording. No timing is asserted: the table must have its rows, a positive cost
in every timed row and VQF as the reference (× VQF 1.00)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from debian_tools import debian_tool
from contract import layout
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import pf_cost  # noqa: E402  (a script folder, not a package)

#: Seconds of the recording: enough samples for the filter to update (decimation 16), short
#: enough for a test.
SECONDS = 3.0


def test_pf_cost_table_has_every_row(tmp_path):
    debian_tool("gcc")
    data = simulate(load_scenario(SCENARIO_DIR / "eval_handheld.toml"), seed=1)
    data = data.slice(slice(0, int(SECONDS / float(np.median(np.diff(data.t))))))
    rows = pf_cost.measure(data, layout.identity_coefficients(), {"pf_hold_prior": 0.0}, tmp_path, repeats=1)
    text = pf_cost.table(rows)
    labels = [row.label for row in rows]
    assert [label.split(" ")[0] for label in labels] == ["filter", "filter", "filter", "filter", "VQF"]
    assert labels[0].startswith("filter off") and labels[3].startswith("filter adapting from the start")
    assert all(row.samples == len(data) for row in rows if "held" not in row.label)
    assert all(row.us is None or row.us > 0.0 for row in rows)
    lines = text.splitlines()
    assert lines[0] == "| configuration | samples | µs/sample | × VQF |" and len(lines) == 2 + len(rows)
    assert lines[-1].endswith("| 1.00 |")
