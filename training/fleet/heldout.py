"""A unit's held-out errors: its trained model run by the C runtime (the FMU's code, at the
settings `train` wrote) on the unit's test recordings, against their truth."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from contract.layout import settings_array
from contract.mounting import array_codes
from training.artefact import coefficients_array, load_artefact, settings_dict
from training.data.io import read_imu_csv
from training.evaluate import compute_metrics
from training.main_job import recording_parameters, settings_with
from training.mounting import body_references

#: The errors reported, as named by training.evaluate.Metrics.as_dict, with their units in the name.
HELD_OUT_METRICS = ("rate_err_dps", "field_err_ut")


def held_out_errors(model_path: str | Path, test_paths: list[Path]) -> dict[str, float]:
    """{metric: RMS over all test recordings' samples} (HELD_OUT_METRICS) of the model's outputs."""
    from training.runtime import run_batch
    artefact = load_artefact(model_path)
    coefficients = coefficients_array(artefact)
    base = np.asarray(settings_array(settings_dict(artefact)))
    squares = {k: [] for k in HELD_OUT_METRICS}
    for path in test_paths:
        data = read_imu_csv(path)
        s = settings_with(base, recording_parameters(data))
        out = run_batch(coefficients, s, data.t, data.inputs([a["column"] for a in artefact.aux_inputs]))
        metrics = compute_metrics(out, body_references(data, array_codes(s))).as_dict()
        for k in HELD_OUT_METRICS:
            squares[k].append((metrics[k] ** 2, len(data)))
    return {k: float(np.sqrt(sum(v * n for v, n in rows) / sum(n for _, n in rows))) for k, rows in squares.items()}
