"""What `train` did, for the user: a printed summary and OUT/calibration.md with plots.

Per triad: the reference source, bias, scale factors and cross-axis terms of A·G at the centre
temperature t0, the fit's error before → after, and the temperature span; per recording the
field-norm and gravity-norm spreads before → after; the FMU settings `train` chose; every note.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from contract.layout import TRIAD_ORDER
from training.artefact import ModelArtefact
from training.data.dataset import ImuData
from training.data.earth import recordings_gravity
from training.data.reference_source import SOURCE_TEXT
from training.display import DISPLAY
from training.completeness import gap_headline, is_gap
from training.attitude.replay import REFERENCE_DECISIONS
from training.models.fit_quality import BIAS_FALLBACK_NOTE, at_t0, cross_axis_deg, is_warning, scale_factors
from training.models.thermal import apply_thermal

UNITS = {"gyr": "rad/s", "acc": "m/s²", "mag": "µT"}
NAMES = {"gyr": "gyroscope", "acc": "accelerometer", "mag": "magnetometer"}
#: Settings the summary reports, with their display unit and factor.
SETTINGS_SHOWN = {"attitude_mode": ("", 1.0), "rest_gyro_threshold": ("°/s", float(np.rad2deg(1.0))),
                  "gyro_noise": ("°/s/√Hz", float(np.rad2deg(1.0))), "field_norm": ("µT", 1.0),
                  "field_dip": ("°", float(np.rad2deg(1.0))), "declination": ("°", float(np.rad2deg(1.0))),
                  "pf_measurement_noise": ("µT", 1.0), "enable_elm": ("", 1.0), "enable_psobp": ("", 1.0),
                  "mount_x": ("", 1.0), "mount_y": ("", 1.0), "mount_z": ("", 1.0), "gyro_hold": ("", 1.0),
                  "mag_heading": ("", 1.0), "motion_bias": ("", 1.0), "acc_norm_tolerance": ("%", 100.0),
                  "enable_pf": ("", 1.0)}
#: Rows of a recording plotted at most (evenly thinned): enough to show every rest and motion.
PLOT_ROWS = 20000


def _fit_line(stats: dict, triad: str) -> str:
    """'error before → after' from the fit statistics of a triad, or ''."""
    unit, factor = DISPLAY[triad]
    if "rms_before" in stats and "rms_after" in stats:
        return f"residual against the reference {stats['rms_before'] * factor:.4g} → {stats['rms_after'] * factor:.4g} {unit} RMS"
    residuals = stats.get("residual") or {}
    return "; ".join(f"{name} {v['before']:.4g} → {v['after']:.4g}" for name, v in residuals.items()
                     if v.get("before") is not None and v.get("after") is not None)


def triad_summary(artefact: ModelArtefact, triad: str) -> list[str]:
    """Lines describing one triad's calibration."""
    model, stats = artefact.thermal[triad], artefact.fit_stats.get(triad, {})
    source = stats.get("reference", "none")
    head = f"{NAMES[triad]}: reference: {SOURCE_TEXT.get(source, source)}"
    if not model.enabled:
        loud = [n.split(": ", 1)[1] for n in artefact.notes if n.startswith(f"{triad}: NOT EXPORTED")]
        return [head, f"  not calibrated (identity): {loud[0]}" if loud else "  not calibrated (identity): see the notes"]
    unit, factor = DISPLAY[triad]
    a, b = at_t0(model)
    lines = [head,
             f"  bias at {model.t0:.1f} °C: {_with_se(b * factor, _se(stats, 'bias', factor), '+.4g')} {unit}",
             f"  scale factors (raw per true, 1 = nominal): {_with_se(scale_factors(model), _se(stats, 'scale_factors'), '.5f')}",
             f"  non-orthogonality (xy xz yz): {_with_se(_nonorthogonality(a), _se(stats, 'nonorthogonality_deg'), '+.3f')} °",
             f"  correction matrix A (model.json): diagonal [{', '.join(f'{v:.5f}' for v in np.diag(a))}], "
             f"cross-axis (xy xz yx yz zx zy) [{', '.join(f'{v:+.3f}' for v in cross_axis_deg(a))}] °",
             f"  temperature model: degree {model.degree}" + (
                 f", fitted over {model.t0 - model.ts:.1f} … {model.t0 + model.ts:.1f} °C" if model.degree else "")]
    if stats.get("held"):
        lines.append(f"  held at nominal (the recording does not determine them): {', '.join(stats['held'])}")
    fallback = [n.split(": ", 1)[1] for n in artefact.notes if n.startswith(f"{triad}: {BIAS_FALLBACK_NOTE}")]
    if fallback:
        lines.insert(1, f"  {fallback[0]}")
    choice = stats.get("degree_choice") or {}
    if choice.get("rule"):
        lines.append(f"  degree choice: {choice['rule']}")
    fit = _fit_line(stats, triad)
    if fit:
        lines.append(f"  {fit} (on the calibration data)")
    held = stats.get("held_out") or {}
    if held.get("before") is not None and held.get("after") is not None:
        unit, factor = DISPLAY[triad]
        metric = held["metric"].replace(f"[{UNITS[triad]}]", f"[{unit}]")
        lines.append(f"  held-out ({held['holdout']}): {metric} "
                     f"{held['before'] * factor:.4g} → {held['after'] * factor:.4g}")
    for key in ("fitted", "why_not_more", "rest_windows", "poses", "segments", "coverage"):
        if stats.get(key) not in (None, ""):
            lines.append(f"  {key.replace('_', ' ')}: {stats[key]}")
    return lines


def _se(stats: dict, key: str, factor: float = 1.0) -> np.ndarray | None:
    """The standard errors stats['<key>_se'] (3,) times `factor`, or None when the fit gave none."""
    value = stats.get(f"{key}_se")
    return None if value is None else np.asarray(value, dtype=float) * factor


def _with_se(values, se: np.ndarray | None, spec: str) -> str:
    """'[v ± s, ...]' (or '[v, ...]' without standard errors) of three values."""
    if se is None:
        return "[" + ", ".join(f"{v:{spec}}" for v in values) + "]"
    return "[" + ", ".join(f"{v:{spec}} ± {s:.2g}" for v, s in zip(values, se)) + "]"


def _nonorthogonality(a: np.ndarray) -> list[float]:
    """Non-orthogonality [°] of the raw axes (xy, xz, yz) implied by the correction a (3, 3)."""
    from training.selfcal.accel import gain_summary
    return list(gain_summary(a)["nonorthogonality_deg"].values())


def _protocol_lines(artefact: ModelArtefact) -> list[str]:
    """The recognised protocol and what each of its parts identified (self-calibration only)."""
    protocol = artefact.fit_stats.get("protocol")
    if not protocol:
        return []
    lines = [f"recognised protocol: {protocol['name']}"]
    for part, params in protocol.get("identified", {}).items():
        lines.append(f"  {part}: {', '.join(params)}")
    return lines


def incomplete_lines(artefact: ModelArtefact) -> list[str]:
    """The summary's opening block: every recorded triad left wholly or partly uncalibrated."""
    gaps = [n for n in artefact.notes if is_gap(n)]
    if not gaps:
        return []
    return [f"INCOMPLETE CALIBRATION ({len(gaps)} triad(s)): the model was written, but not everything the "
            "recording holds was calibrated (why, and what to record: WARNINGS below)"] + [
        f"  ! {gap_headline(g)}" for g in gaps]


def norm_spreads(artefact: ModelArtefact, datasets: list[ImuData]) -> list[dict]:
    """Per recording: field-norm spread 100·std/mean [%] and accelerometer-norm RMS deviation from
    its median [m/s²], raw and calibrated (finite rows)."""
    out = []
    for d in datasets:
        row = {"name": d.name}
        for triad in ("mag", "acc"):
            raw = getattr(d, triad)
            ok = np.all(np.isfinite(raw), axis=1)
            if ok.sum() < 2:
                continue
            cal = apply_thermal(artefact.thermal[triad], raw[ok], d.temp[ok])
            for label, x in (("raw", raw[ok]), ("calibrated", cal)):
                norm = np.linalg.norm(x, axis=1)
                row[f"{triad}_{label}"] = (100.0 * float(np.std(norm) / np.mean(norm)))
        out.append(row)
    return out


def summary_text(artefact: ModelArtefact, datasets: list[ImuData]) -> str:
    """The calibration summary `train` prints (plain text)."""
    from training.mounting import frame_lines
    lines = [f"calibration of {', '.join(d.name for d in datasets)} "
             f"({sum(len(d) for d in datasets)} samples, seed {artefact.seed})"]
    lines += frame_lines(artefact.settings, artefact.notes)  # issue 35: the frame first
    lines += [n for n in artefact.notes if n.startswith(REFERENCE_DECISIONS)]
    lines += incomplete_lines(artefact) + _protocol_lines(artefact)
    for triad in TRIAD_ORDER:
        lines += triad_summary(artefact, triad)
    for row in norm_spreads(artefact, datasets):
        parts = [f"{what} norm spread {row[f'{k}_raw']:.2f} → {row[f'{k}_calibrated']:.2f} %"
                 for k, what in (("mag", "field"), ("acc", "specific-force")) if f"{k}_raw" in row]
        if parts:
            lines.append(f"{row['name']}: " + ", ".join(parts))
    if artefact.noise is not None:
        from training.noise.report import summary_lines
        lines += summary_lines(artefact.noise, compact=True) + ["  (per axis with CIs: model.json 'noise', imu.yaml)"]
    shown = []
    for name, (unit, factor) in SETTINGS_SHOWN.items():
        if name in artefact.settings:
            shown.append(f"{name} = {artefact.settings[name] * factor:.4g}{(' ' + unit) if unit else ''}")
    lines.append("FMU settings written: " + ", ".join(shown))
    gapped = {n.split(":", 1)[0] for n in artefact.notes if is_gap(n)}
    warnings = [n for n in artefact.notes if is_warning(n)
                and not (": NOT EXPORTED" in n and n.split(":", 1)[0] in gapped)]  # the gap repeats it
    if warnings:
        lines.append(f"WARNINGS ({len(warnings)}): the fit is outside what this sensor class or the data support")
        lines += [f"  ! {w}" for w in warnings]
    return "\n".join(lines)


def _thinned(d: ImuData) -> np.ndarray:
    """Row indices of d, evenly thinned to at most PLOT_ROWS."""
    return np.unique(np.linspace(0, len(d) - 1, min(len(d), PLOT_ROWS)).astype(int))


def _plot_norms(artefact: ModelArtefact, datasets: list[ImuData], path: Path) -> Path:
    """Field and specific-force norms over time, raw and calibrated, with temperature."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True)
    offset = 0.0
    for d in datasets:
        k = _thinned(d)
        t = d.t[k] - d.t[0] + offset
        for ax, triad, unit in ((axes[0], "mag", "µT"), (axes[1], "acc", "m/s²")):
            raw = d.__getattribute__(triad)[k]
            ax.plot(t, np.linalg.norm(raw, axis=1), color="0.6", lw=0.6, label="raw" if offset == 0 else None)
            ax.plot(t, np.linalg.norm(apply_thermal(artefact.thermal[triad], raw, d.temp[k]), axis=1),
                    color="C0", lw=0.6, label="calibrated" if offset == 0 else None)
            ax.set_ylabel(f"|{triad}| [{unit}]")
        axes[2].plot(t, d.temp[k], color="C3", lw=0.8)
        offset = t[-1] + 1.0
    axes[0].axhline(artefact.settings.get("field_norm", np.nan), color="k", ls=":", lw=0.8, label="field_norm")
    axes[1].axhline(recordings_gravity(datasets)[0], color="k", ls=":", lw=0.8, label="local g")
    axes[2].set_ylabel("temperature [°C]")
    axes[2].set_xlabel("time [s] (recordings one after another)")
    for ax in axes[:2]:
        ax.legend(loc="upper right", fontsize=8)
    fig.suptitle("Invariants before and after calibration")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _plot_ellipsoid(artefact: ModelArtefact, datasets: list[ImuData], path: Path) -> Path:
    """The field samples projected on the xy, xz and yz planes, raw and calibrated."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    raw = np.concatenate([d.mag[_thinned(d)] for d in datasets])
    temp = np.concatenate([d.temp[_thinned(d)] for d in datasets])
    ok = np.all(np.isfinite(raw), axis=1)
    cal = apply_thermal(artefact.thermal["mag"], raw[ok], temp[ok])
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.2))
    for ax, (i, j) in zip(axes, ((0, 1), (0, 2), (1, 2))):
        ax.plot(raw[ok, i], raw[ok, j], ".", ms=0.5, color="0.6", label="raw")
        ax.plot(cal[:, i], cal[:, j], ".", ms=0.5, color="C0", label="calibrated")
        ax.set_xlabel(f"{'xyz'[i]} [µT]")
        ax.set_ylabel(f"{'xyz'[j]} [µT]")
        ax.set_aspect("equal", adjustable="datalim")
    axes[0].legend(markerscale=10, fontsize=8)
    fig.suptitle("Magnetometer: ellipsoid before, sphere after")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_calibration_report(artefact: ModelArtefact, datasets: list[ImuData], out_dir: str | Path) -> Path:
    """OUT/calibration.md (summary, spreads, settings, notes) with calibration_norms.png and, when the
    magnetometer was recorded, calibration_field.png; returns the Markdown path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    lines = ["# Calibration", "", "Written by `imufmu train`; the model is `model.json` beside this file.",
             "", "```", summary_text(artefact, datasets), "```", ""]
    lines += ["![norms](calibration_norms.png)", ""]
    _plot_norms(artefact, datasets, out_dir / "calibration_norms.png")
    if any(d.has("mag") for d in datasets):
        _plot_ellipsoid(artefact, datasets, out_dir / "calibration_field.png")
        lines += ["![field](calibration_field.png)", ""]
    if artefact.notes:
        lines += ["## Notes", ""] + [f"- {n}" for n in artefact.notes] + [""]
    path = out_dir / "calibration.md"
    path.write_text("\n".join(lines))
    return path
