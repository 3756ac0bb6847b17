"""FMU settings from the calibration data: what `train` writes beside the coefficients.

The sidecars (or the IGRF field at their site) give the earth field; the calibrated gyro at rest
gives its noise density, the bias the calibration leaves and the rest-detection threshold; the
calibrated accelerometer at rest the norm error its filter must not take for linear acceleration; the
calibrated field gives the particle filter's noise and thresholds (training.models.pf_settings); the
self-calibration's field norm and dip stand in when the sidecars say nothing; a declared mounting,
else the direction of gravity at rest, gives the mounting (training.mounting: one rule, with or
without a reference).
"""
from __future__ import annotations

import numpy as np

from contract.errors import ModelError
from contract.layout import SETTING_RANGES, settings_defaults
from contract.schema import number_text, range_text, setting_problem
from training.data.dataset import ImuData
from training.data.reference import true_runs
from training.data.reference_source import TriadReference
from training.attitude.acc_norm import acc_norm_tolerance_setting
from training.attitude.magnetic_trust import mag_heading_setting
from training.models.thermal import ThermalModel, apply_thermal
from training.mounting import recommended_mounting

#: A sample counts as static for the gyro bias residual when the true rate is below this
#: [rad/s] (0.3 °/s: far above the reference noise of a rate table, far below any motion).
STATIC_RATE = 0.005
#: Lower bound of the recommended gyro_bias_residual [rad/s]: 1e-5 rad/s ≈ 2 °/h, the bias
#: instability of a good consumer MEMS gyro. A fit to simulated data leaves a near-zero mean
#: residual, but run-to-run bias changes that no calibration captures remain in the field.
GYRO_BIAS_RESIDUAL_FLOOR = 1e-5
#: Shortest rest run [samples] whose statistics count: 20 samples give a std within ~16 %.
MIN_REST_RUN = 20
#: rest_gyro_threshold ≥ this many σ of the per-sample gyro noise: the runtime's detector needs
#: every sample of 1.5 s within the threshold of the low-passed rate; at 5σ a still sensor at
#: 300 Hz passes with > 99 % probability (at 4σ, ~97 %).
REST_NOISE_SIGMAS = 5.0
#: rest_gyro_threshold ≥ this many times the largest bias the calibration leaves at rest (run
#: means, between and within recordings): the detector also requires the low-passed rate inside
#: the threshold, so a residual bias at half of it is still accepted.
REST_BIAS_MARGIN = 2.0
#: bias_learning_limit = this many times the largest axis's rest noise σ: the online bias learning
#: (sources/ImuBiasLearning.h) may absorb a power-up bias change of up to 10 σ per coefficient. One
#: session cannot measure the run-to-run change; a change beyond 10 σ is a fault or a recalibration.
BIAS_LEARNING_SIGMAS = 10.0
#: Sidecar earth-field magnitudes of the training sets may differ by this much [µT] before
#: the artefact warns that their mean is a poor single field_norm.
FIELD_NORM_SPREAD = 1.0


def sidecar_values(datasets: list[ImuData], key: str, igrf: list[str] | None = None) -> list[float]:
    """earth_field[key] (norm_ut, dip_deg, declination_deg) of every dataset whose sidecar gives it,
    else of the IGRF field at the sidecar's site (training.data.geomag.site_field) when it gives one;
    `igrf`, when given, collects the names of the recordings whose value came from IGRF."""
    from training.data.geomag import site_field
    values = []
    for d in datasets:
        value = (d.meta.get("earth_field") or {}).get(key)
        if value is None:
            try:
                field = site_field(d.meta)
            except ValueError as e:
                raise ModelError(f"{d.name}: {e}") from None
            value = getattr(field, key) if field is not None else None
            if value is not None and igrf is not None:
                igrf.append(d.name)
        if value is not None:
            values.append(float(value))
    return values


def _igrf_note(setting: str, key: str, value: float, unit: str, names: list[str]) -> str:
    """'field_norm: 48.21 µT, from the IGRF model at the sidecar's site of REC (its earth_field.norm_ut is null or absent)'."""
    return (f"{setting}: {value:.4g} {unit}, from the IGRF model at the sidecar's site of {', '.join(names)} "
            f"(earth_field.{key} is null or absent there)")


def _rate_hz(data: ImuData) -> float:
    """Sample rate [Hz]: sidecar rate_hz, else 1 / median time step."""
    rate = data.meta.get("rate_hz")
    return float(rate) if rate else float(1.0 / np.median(np.diff(data.t)))


def _rest_masks(refs: dict[str, TriadReference], selfcal) -> list[tuple[ImuData, np.ndarray, np.ndarray]]:
    """[(recording, true rate (N, 3) rad/s, rest mask (N,))] of the recordings that show the gyro at
    rest: where the reference rate is below STATIC_RATE, or the self-calibration's rest windows."""
    ref = refs["gyr"]
    if ref.source != "none":
        return [(d, d.ref_gyr, np.all(np.isfinite(d.ref_gyr), axis=1)
                 & (np.linalg.norm(np.nan_to_num(d.ref_gyr, nan=np.inf), axis=1) < STATIC_RATE))
                for d in ref.datasets]
    return [(d, np.zeros_like(d.gyr), mask) for d, mask in zip(ref.datasets, selfcal.rest_masks)]


def _rest_residuals(recordings, model: ThermalModel):
    """[(per-run mean residual (3,), per-run variance (3,), rate_hz)] over the rest runs; residual =
    compensated gyro − true rate [rad/s], finite rows."""
    out = []
    for d, truth, mask in recordings:
        residual = apply_thermal(model, d.gyr, d.temp) - truth
        for a, b in true_runs(mask & np.all(np.isfinite(residual), axis=1)):
            if b - a < MIN_REST_RUN:
                continue
            out.append((residual[a:b].mean(axis=0), residual[a:b].var(axis=0), _rate_hz(d), b - a))
    return out


def gyro_rest_settings(runs) -> dict[str, float]:
    """gyro_noise, gyro_bias_residual, rest_gyro_threshold and bias_learning_limit from the gyro at rest
    after calibration.

    runs: [(mean residual (3,), variance (3,), rate_hz, samples)] per rest run. gyro_noise
    [rad/s/√Hz] = σ / √f_s (IEEE Std 952), σ the per-sample std within the runs (RMS over axes);
    gyro_bias_residual [rad/s] = largest |mean| of the residual over all rest samples per axis (not
    below GYRO_BIAS_RESIDUAL_FLOOR); rest_gyro_threshold [rad/s] = max(REST_NOISE_SIGMAS · σ of the
    noisiest axis, REST_BIAS_MARGIN · largest |run mean|): the runtime's rest detector must accept
    every sample of a still sensor (noise) and the bias the calibration leaves (it checks the
    low-passed rate against the threshold too), and no more — a larger threshold takes a slow turn
    for a bias; bias_learning_limit [rad/s] = BIAS_LEARNING_SIGMAS · σ of the noisiest axis.
    """
    weights = np.array([n for *_, n in runs], dtype=float)
    means = np.array([m for m, *_ in runs])
    variances = np.array([v for _, v, *_ in runs])
    sigma_axis = np.sqrt(np.average(variances, axis=0, weights=weights))
    density = [np.sqrt(np.mean(v)) / np.sqrt(f) for _, v, f, _ in runs]
    bias = np.abs(np.average(means, axis=0, weights=weights))
    return {"gyro_noise": float(np.average(density, weights=weights)),
            "gyro_bias_residual": float(max(bias.max(), GYRO_BIAS_RESIDUAL_FLOOR)),
            "rest_gyro_threshold": float(max(REST_NOISE_SIGMAS * sigma_axis.max(),
                                             REST_BIAS_MARGIN * np.abs(means).max())),
            "bias_learning_limit": float(BIAS_LEARNING_SIGMAS * sigma_axis.max())}


def _field_settings(datasets: list[ImuData], selfcal, notes: list[str]) -> dict[str, float]:
    """field_norm [µT], field_dip [rad] and declination [rad]: from the sidecars, else from the
    self-calibration of the magnetometer, else the defaults (with a note)."""
    settings, mag = {}, (selfcal.report.get("mag", {}) if selfcal else {})
    igrf = {"norm_ut": [], "dip_deg": [], "declination_deg": []}
    norms, dips = sidecar_values(datasets, "norm_ut", igrf["norm_ut"]), sidecar_values(datasets, "dip_deg", igrf["dip_deg"])
    if norms:
        settings["field_norm"] = float(np.mean(norms))
        if max(norms) - min(norms) > FIELD_NORM_SPREAD:
            notes.append(f"field_norm: sidecar values {norms} µT differ; using their mean")
        if igrf["norm_ut"]:
            notes.append(_igrf_note("field_norm", "norm_ut", settings["field_norm"], "µT", igrf["norm_ut"]))
    elif mag.get("field_norm_ut"):
        settings["field_norm"] = float(mag["field_norm_ut"])
        notes.append(f"field_norm: {settings['field_norm']:.2f} µT from the magnetometer calibration "
                     f"({mag.get('field_norm_source', 'self-calibration')})")
    else:
        notes.append("field_norm: no earth_field.norm_ut in the sidecars and no magnetometer "
                     "calibration; default kept")
    if dips:
        settings["field_dip"] = float(np.deg2rad(np.mean(dips)))
        if igrf["dip_deg"]:
            notes.append(_igrf_note("field_dip", "dip_deg", float(np.mean(dips)), "°", igrf["dip_deg"]))
    elif mag.get("dip_deg") is not None:
        settings["field_dip"] = float(np.deg2rad(mag["dip_deg"]))
        notes.append(f"field_dip: {mag['dip_deg']:.2f}° estimated at the rest poses")
    declinations = sidecar_values(datasets, "declination_deg", igrf["declination_deg"])
    if declinations:
        settings["declination"] = float(np.deg2rad(np.mean(declinations)))
        if igrf["declination_deg"]:
            notes.append(_igrf_note("declination", "declination_deg", float(np.mean(declinations)), "°",
                                    igrf["declination_deg"]))
    unknown = [d.name for d in datasets if d.ref_q is not None and (d.meta.get("earth_field") or {}).get("declination_deg") is None
               and d.name not in igrf["declination_deg"]]
    if unknown:
        notes.append(f"declination: {', '.join(unknown)} give no declination nor a site: the FMU's declination "
                     f"(true minus magnetic heading where it runs) stays {np.rad2deg(settings.get('declination', 0.0)):.4g}°; "
                     "set it there (an angle estimated from a recording is its reference frame's, not a site's)")
    return settings


def _pf_settings(datasets: list[ImuData], model: ThermalModel, field_norm: float,
                 notes: list[str]) -> dict[str, float]:
    """Particle-filter settings from the calibrated field of the recordings (training.models.pf_settings):
    what the filter will see at run time, so that switching it on declares no change that is noise."""
    from training.models.pf_settings import pf_settings_from_calibration
    usable = [d for d in datasets if d.has("mag")]
    if not usable:
        notes.append("pf_*: no magnetometer recorded; particle-filter defaults kept")
        return {}
    field = np.concatenate([apply_thermal(model, d.mag, d.temp) for d in usable])
    t = np.concatenate([d.t for d in usable])
    try:
        return pf_settings_from_calibration(field, t, field_norm, float(np.median([_rate_hz(d) for d in usable])))
    except ValueError as e:
        notes.append(f"pf_*: {e}; particle-filter defaults kept")
        return {}


def recommended_settings(datasets: list[ImuData], refs: dict[str, TriadReference],
                         thermal: dict[str, ThermalModel], selfcal, notes: list[str],
                         mounting=None) -> dict[str, float]:
    """FMU parameter values from the sidecars, the calibration and the sensor at rest (defaults
    otherwise); appends a note for each value left at its default or taken from inconsistent data.
    mounting: the codes `train --mounting` declared (training.mounting.recommended_mounting), or None."""
    settings = settings_defaults()
    settings.update(_field_settings(datasets, selfcal, notes))
    recordings = _rest_masks(refs, selfcal)
    runs = _rest_residuals(recordings, thermal["gyr"]) if thermal["gyr"].enabled else []
    if runs:
        settings.update(gyro_rest_settings(runs))
        if len(recordings) < 2:
            notes.append("rest_gyro_threshold: one recording shows only this power-up's bias; record a "
                         "second session (power-cycled) so that train sees the run-to-run bias change")
    else:
        notes.append("gyro_noise, gyro_bias_residual, rest_gyro_threshold, bias_learning_limit: no gyro at rest after "
                     "calibration; defaults kept")
    settings.update(mag_heading_setting(datasets, thermal["mag"], settings, notes))
    settings.update(acc_norm_tolerance_setting(datasets, thermal["acc"], notes))
    settings.update(_pf_settings(datasets, thermal["mag"], settings["field_norm"], notes))
    settings.update(recommended_mounting(datasets, notes, mounting))
    return held_in_range(settings, notes)


def held_in_range(settings: dict[str, float], notes: list[str]) -> dict[str, float]:
    """`settings` with every finite real value the data gave outside the range the FMU accepts held at the
    nearest bound, and a warning for each: the data asked for something the runtime refuses (a gyro bias at
    rest that the calibration does not explain, 0.8 °/s per volt of an unrecorded supply sag × 520: a rest
    threshold of several rad/s, and `train` stopped with the runtime's refusal)."""
    out = dict(settings)
    for name, value in settings.items():
        problem = setting_problem(name, value)
        r = SETTING_RANGES.get(name)
        if problem is None or r is None or r.type != "Real" or not np.isfinite(value):
            continue
        low = np.nextafter(r.min, r.max) if r.min_open else r.min
        out[name] = float(min(max(value, low), np.nextafter(r.max, r.min) if r.max_open else r.max))
        notes.append(f"warning: {name} = {number_text(value)} from the calibration data is outside the range the FMU "
                     f"accepts, {range_text(name)}; held at {number_text(out[name])}: the data do not fit what the "
                     "FMU can represent — check the recordings (rests, units, disturbances)")
    return out
