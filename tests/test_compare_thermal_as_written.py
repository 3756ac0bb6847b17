"""The PSO-BP paper's comparison as written (issue 33 item 5): the piecewise polynomial with one
segment per temperature point, plain BP as the source trains it, PSO-BP in the source's form, each
beside the product's variant (training/bench/compare_thermal.py, `as_written=True`)."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from training.bench.compare_thermal import (AS_WRITTEN_MODELS, BP_WRITTEN, FORM_ROWS, PIECEWISE_WRITTEN, SOURCE,
                                            _as_written_run, _split, fit_piecewise)
from training.bench.doc_tables import ROOT
from training.models.psobp import EnableDecision, apply_psobp

#: Four training "plateaus" as the protocol's warm-ups span them [°C]: equally many targets each,
#: their ranges separated by gaps. Equal-width bands over -10..42 °C cut the second one at 16 °C.
PLATEAUS_C = ((-10.0, 0.0), (7.0, 17.0), (19.0, 29.0), (32.0, 42.0))
#: Least-squares polynomials reproduce an exact quadratic to rounding [rad/s].
EXACT_RAD_S = 1e-9
#: BP budget of the network rows in the small run (epochs).
SMALL_EPOCHS = 15


def _plateau_targets(per_plateau: int = 50):
    """Targets of four plateaus, each with its own quadratic bias (3 axes), in time order."""
    temp, bias = [], []
    for k, (lo, hi) in enumerate(PLATEAUS_C):
        tk = np.linspace(lo, hi, per_plateau)
        bk = 1e-3 * (k + 1) * np.column_stack([1.0 + 0.1 * tk, 0.01 * tk ** 2, -tk + 0.02 * tk ** 2])
        temp.append(tk)
        bias.append(bk)
    return np.concatenate(temp), np.concatenate(bias)


def test_count_bands_give_one_band_per_plateau():
    temp, bias = _plateau_targets()
    piece = fit_piecewise(temp, bias, degree=2, segments=4, bands="count")
    assert np.max(np.abs(piece.bias(temp) - bias)) < EXACT_RAD_S
    # Equal-width bands mix two plateaus in one band: not exact.
    width = fit_piecewise(temp, bias, degree=2, segments=4, bands="width")
    assert np.max(np.abs(width.bias(temp) - bias)) > 1e3 * EXACT_RAD_S


def test_unknown_band_rule_is_refused():
    temp, bias = _plateau_targets()
    with pytest.raises(ValueError, match="band rule"):
        fit_piecewise(temp, bias, degree=2, segments=4, bands="quantile")


def _static_recording(seconds: float = 300.0, rate_hz: float = 5.0):
    """A static unit warming from 0 to 40 °C, bias quadratic in T plus a warm-up term; ref_gyr = 0."""
    t = np.arange(0.0, seconds, 1.0 / rate_hz)
    temp = 40.0 * t / seconds
    rng = np.random.default_rng(3)
    bias = 1e-3 * np.column_stack([temp, 0.02 * temp ** 2, -temp])
    gyr = bias + 1e-4 * rng.standard_normal((t.size, 3))
    return SimpleNamespace(t=t, temp=temp, gyr=gyr, ref_gyr=np.zeros_like(gyr))


def test_as_written_rows_are_the_source_forms():
    data = _static_recording()
    train = _split(data.t, 0.6)
    settings = {"hidden": 4, "tau_s": 10.0, "window_s": 10.0, "rest_rad_s": 1e-3, "degree": 2,
                "bp_epochs": SMALL_EPOCHS}
    rows = _as_written_run(data, train, settings, seed=0)
    assert tuple(rows) == AS_WRITTEN_MODELS
    assert PIECEWISE_WRITTEN in rows and rows[PIECEWISE_WRITTEN][2] is None
    static_rows = int(train.sum())
    bias, _, bp = rows[BP_WRITTEN]
    # Plain BP as written: no swarm, single-sample targets, the whole budget, inputs not clamped.
    assert bp.pso_fitness is None and bp.windows == static_rows and bp.epochs == SMALL_EPOCHS
    np.testing.assert_array_equal(bias, apply_psobp(bp.model, data.t, data.temp, clamp_inputs=False))
    assert not np.allclose(bias[~train], apply_psobp(bp.model, data.t, data.temp)[~train])
    source = rows[SOURCE][2]
    assert source.pso_fitness is not None and source.windows == static_rows
    # The product's variants beside them: window-mean targets.
    for name in ("BP", FORM_ROWS[-1]):
        assert rows[name][2].windows < static_rows


def test_as_written_is_refused_for_the_verdict(tmp_path):
    run = subprocess.run([sys.executable, "benchmarks/bench_thermal.py", "verdict", "--as-written", "--out",
                          str(tmp_path)],
                         cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 2
    assert "--as-written applies to plateaus, rate and pan, not to verdict" in run.stderr
    assert "Traceback" not in run.stderr


def _bench_thermal():
    """benchmarks/bench_thermal.py as a module."""
    spec = importlib.util.spec_from_file_location("bench_thermal", ROOT / "benchmarks" / "bench_thermal.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_tau_s_reaches_the_verdict_rule(monkeypatch):
    bench = _bench_thermal()
    seen = []

    def rule(*args, **kwargs):
        seen.append(kwargs["tau_s"])
        return EnableDecision(False, 1.0, 1.0, 1)
    monkeypatch.setattr(bench, "residual_psobp_wins", rule)
    monkeypatch.setattr(bench, "read_imu_csv", lambda path: _static_recording())
    monkeypatch.setattr(bench, "polynomial_compensated", lambda t, gyr, ref_gyr, temp: gyr)
    bench.verdict_rows({"rate": ROOT / "unused.csv"}, [0, 1], bp_epochs=SMALL_EPOCHS, tau_s=0.5)
    assert seen == [0.5, 0.5]


def test_non_positive_tau_s_is_refused_in_one_line(tmp_path):
    run = subprocess.run([sys.executable, "benchmarks/bench_thermal.py", "verdict", "--tau-s", "0", "--out",
                          str(tmp_path)],
                         cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 2
    assert "--tau-s must be positive" in run.stderr and "Traceback" not in run.stderr
