"""A rate reference derived from an attitude reference (motion capture's ref_q) is compared with the
compensated rate through the reference's own derivative filter and as 1 s means, and so is every
candidate's column (training.diagnosis.rate_means, issue 30 item 3).

Truth: the simulator's recording with its rate reference removed, so that loading derives it from ref_q
as on BROAD; the model is trained on the effect-free calibration recording, so an effect injected into
the diagnosed raw rate is exactly what the residual must read.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from training.data.io import write_imu_csv
from training.diagnosis import rate_means
from training.diagnosis.candidates import build_candidates
from training.diagnosis.diagnose import ALPHA, MIN_EXPLAINED, load_recordings, residuals
from training.diagnosis.diagnose_fit import fit_candidates, offset_fit
from training.frames import quat_from_rotvec, quat_multiply
from training.main_job import SCENARIO_DIR
from training.simulator import load_scenario, simulate
from training.train import train

#: White orientation noise of the simulated motion capture per axis [°]: about what BROAD's residual shows
#: above the motion (0.9 °/s RMS per band at 3–15 Hz through a 0.1 s derivative ≈ 6.3/s · σ → σ ≈ 0.14°).
ATTITUDE_NOISE_DEG = 0.1
#: A gyro scale nonlinearity k·ω·|ω| per axis [1/(rad/s)], about 1 % at the simulated motion's 0.5–0.6 rad/s.
NONLINEARITY = np.array([0.01, -0.008, 0.012])
#: The issue's bound on a simulated reading.
READING_TOLERANCE = 0.15


@pytest.fixture(scope="module")
def derived_rate(tmp_path_factory):
    """The simulated diagnosis recording with its rate reference removed (derived again from ref_q by a
    smoothed derivative when loaded), a model trained on the clean calibration, and the true rate."""
    tmp = tmp_path_factory.mktemp("derived_rate")
    data = simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_effects.toml"))
    model = train([simulate(load_scenario(SCENARIO_DIR / "variants" / "diag_calibration_clean.toml"))], seed=0,
                  progress=False)
    datasets, _, smoothed = load_recordings([write_imu_csv(replace(data, ref_gyr=None), tmp / "no_rate.csv.gz")])
    return model, datasets[0], smoothed, data, tmp


def test_a_derived_rate_reference_is_met_by_the_rate_filtered_as_it_was(derived_rate):
    """A rate reference differentiated from the attitude with smoothing (0.1 s Savitzky-Golay) lacks the
    motion's fast part, which the compensated rate has; the diagnosis filters the compensated rate the same
    way. Its residual is then within the gyro's own error against the TRUE rate (bound: 1.2× that RMS, the
    filter and the means only average noise); unmatched, the reference's smoothing of the hand-held motion
    is several times larger and no family explains it."""
    model, data, smoothed, truth, _ = derived_rate
    assert smoothed == [True]
    targets = {"gyr": "triad"}
    matched = _rms(residuals(model, [data], targets, smoothed).residual["gyr"])
    unmatched = _rms(residuals(model, [data], targets).residual["gyr"])
    against_truth = _rms(residuals(model, [replace(data, ref_gyr=truth.ref_gyr)], targets).residual["gyr"])
    assert matched <= 1.2 * against_truth < unmatched / 2.0, (matched, against_truth, unmatched)


def _with_nonlinearity_and_noisy_attitude(truth, tmp):
    """The recording with NONLINEARITY in its raw rate and ATTITUDE_NOISE_DEG on ref_q (seeded), loaded so
    that its rate reference is derived from the noisy attitude."""
    rng = np.random.default_rng(3)
    noise = quat_from_rotvec(np.radians(ATTITUDE_NOISE_DEG) * rng.standard_normal((len(truth), 3)))
    data = replace(truth, ref_gyr=None, ref_q=quat_multiply(truth.ref_q, noise),
                   gyr=truth.gyr + NONLINEARITY * truth.gyr * np.abs(truth.gyr))
    datasets, _, smoothed = load_recordings([write_imu_csv(data, tmp / "nonlinear.csv.gz")])
    return datasets, smoothed


def _signed_square_fit(model, datasets, smoothed):
    r = residuals(model, datasets, {"gyr": "triad"}, smoothed)
    candidates = build_candidates(r.signals, ["gyr"])
    family = next(c for c in candidates if c.name == "angular rate signed square")
    base = offset_fit("gyr", r)
    return fit_candidates((family,), r, base, base, len(candidates))


def test_rate_means_read_a_nonlinearity_that_a_noisy_attitude_hides_sample_by_sample(derived_rate, monkeypatch):
    """Against a rate derived from an attitude with motion-capture noise, the scale nonlinearity is selected
    (the loop's rule: p < ALPHA after Bonferroni, ≥ MIN_EXPLAINED of the residual) and read within the
    issue's 15 % on every axis when rate and columns are compared as 1 s means; sample by sample (a window of
    one sample) the differentiated attitude noise hides it (measured: 2 % explained, p 0.02). The columns
    must go through the same filter as the residual: unfiltered beside the means, the reading is 76 % low."""
    model, _, _, truth, tmp = derived_rate
    datasets, smoothed = _with_nonlinearity_and_noisy_attitude(truth, tmp)
    fit = _signed_square_fit(model, datasets, smoothed)
    assert fit.p_value < ALPHA and fit.gain >= MIN_EXPLAINED, (fit.p_value, fit.gain)
    own = fit.coefficients()[0].reshape(3, 3).diagonal()
    assert np.all(np.abs(own - NONLINEARITY) <= READING_TOLERANCE * np.abs(NONLINEARITY)), own
    monkeypatch.setattr(rate_means, "MEAN_WINDOW_S", 0.0)
    sample_by_sample = _signed_square_fit(model, datasets, smoothed)
    assert not (sample_by_sample.p_value < ALPHA and sample_by_sample.gain >= MIN_EXPLAINED)


def test_the_window_mean_is_centred_and_leaves_out_incomplete_windows():
    """A centred mean shifts nothing (a half-sample shift would read as a lag of the rate): a linear ramp is
    its own mean; windows reaching past the ends or over a missing sample are NaN."""
    t = np.arange(500) * 0.01
    x = np.column_stack([t, 2.0 * t])
    x[250, 0] = np.nan
    mean = rate_means.window_mean(x, t)
    half = int(round(rate_means.MEAN_WINDOW_S / 0.01)) // 2
    assert np.allclose(mean[half:-half, 1], x[half:-half, 1])
    assert np.isnan(mean[:half]).all() and np.isnan(mean[-half:]).all()
    assert np.isnan(mean[250 - half:250 + half + 1, 0]).all() and np.isfinite(mean[250 - half - 1, 0])


def _rms(e: np.ndarray) -> float:
    e = e[np.all(np.isfinite(e), axis=1)]
    return float(np.sqrt(np.mean(e * e)))
