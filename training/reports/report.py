"""Human-readable results of the main job: a console table and a Markdown report with PNG plots."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from contract.layout import OUTPUTS
from training.evaluate import ACCEPTANCE, absent_note, present, tilt_heading_errors

#: Rows of the summary table: metric key, label with unit.
ROWS = (("rate_err_dps", "corrected rate error RMS [°/s]"),
        ("accel_err_ms2", "corrected specific-force error RMS [m/s²]"),
        ("field_err_ut", "corrected field error RMS [µT]"),
        ("roll_err_deg", "roll RMSE [°] (|pitch| < 80°)"),
        ("pitch_err_deg", "pitch RMSE [°]"),
        ("yaw_err_deg", "yaw RMSE [°] (|pitch| < 80°)"),
        ("tilt_err_deg", "inclination error RMS [°]"),
        ("heading_err_deg", "heading error RMS [°]"))


def _fmt(v: float) -> str:
    """Number with 4 significant digits, '—' for NaN."""
    return "—" if v is None or not np.isfinite(v) else f"{v:.4g}"


def summary_table(summary) -> str:
    """Markdown table: per scenario and metric the raw value, the corrected value, the bound."""
    lines = ["| scenario | metric | raw | ImuFusion FMU | bound | ok |",
             "|---|---|---:|---:|---:|:-:|"]
    for s in summary.scenarios:
        for key, label in ROWS:
            bound = ACCEPTANCE.get(key)
            ok = "" if bound is None else ("yes" if s.corrected[key] <= bound else "NO")
            lines.append(f"| {s.name} | {label} | {_fmt(s.raw.get(key))} | "
                         f"{_fmt(s.corrected[key])} | {_fmt(bound)} | {ok} |")
    return "\n".join(lines)


def _tilt_heading_deg(out: np.ndarray, data) -> np.ndarray:
    """(N, 2) inclination and heading errors [°] of runtime outputs `out`; NaN (a gap in the plot,
    not a figure) where the accelerometer resp. magnetometer is absent (see the report's note)."""
    err = np.rad2deg(tilt_heading_errors(out, data))
    err[~present(out, "accel"), 0] = np.nan
    err[~present(out, "field"), 1] = np.nan
    return err


def _plot_scenario(s, path: Path) -> Path:
    """Attitude error and rate error over time for one scenario, raw vs corrected."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = s.data.t - s.data.t[0]
    fig, axes = plt.subplots(3, 1, figsize=(10, 8.5), sharex=True)
    # Inclination and heading errors are defined at every attitude (roll and yaw are not at
    # pitch ±90°, which rotation scenarios pass through).
    err = _tilt_heading_deg(s.out, s.data)
    err_raw = _tilt_heading_deg(s.out_raw, s.data)
    for i, name in enumerate(("inclination", "heading")):
        axes[0].plot(t, err_raw[:, i], lw=0.6, label=name)
        axes[1].plot(t, err[:, i], lw=0.8, label=name)
    axes[0].set_ylabel("attitude error [°]\nraw sensors")
    axes[1].set_ylabel("attitude error [°]\nImuFusion FMU")
    for ax in axes[:2]:
        ax.legend(ncol=3, fontsize=7)
    cols = [OUTPUTS.index(c) for c in ("rate_x", "rate_y", "rate_z")]
    rate_err = np.rad2deg(s.out[:, cols] - s.data.ref_gyr)
    raw_err = np.rad2deg(s.data.gyr - s.data.ref_gyr)
    for i, ax in enumerate("xyz"):
        axes[2].plot(t, raw_err[:, i], lw=0.5, alpha=0.5, label=f"{ax} raw")
        axes[2].plot(t, rate_err[:, i], lw=0.5, label=f"{ax} corrected")
    axes[2].set_ylabel("rate error [°/s]")
    axes[2].set_xlabel("time [s]")
    axes[2].legend(ncol=3, fontsize=7)
    fig.suptitle(f"{s.name}: errors against simulator truth")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_report(summary, out_dir: Path) -> Path:
    """Write `report.md` with the summary table, timings and one plot per scenario."""
    out_dir = Path(out_dir)
    plots = out_dir / "plots"
    plots.mkdir(parents=True, exist_ok=True)
    parts = ["# ImuFusion main job report", "",
             f"- model artefact: `{os.path.relpath(summary.model_path, out_dir)}`",
             f"- FMU: `{os.path.relpath(summary.fmu_path, out_dir)}`",
             f"- FMU validation problems: {len(summary.validation_problems)}"
             + "".join(f"\n  - {p}" for p in summary.validation_problems),
             "", "## Accuracy against simulator truth", "",
             "Raw = the uncompensated sensors (rates, specific force, field) and the same attitude "
             "filter run on them; ImuFusion FMU = the trained FMU co-simulated with fmpy.", "",
             summary_table(summary), "",
             "| scenario | samples | FMU vs batch runtime, max abs difference |", "|---|---:|---:|"]
    parts += [f"| {s.name} | {s.samples} | {s.fmu_vs_batch_max_diff:.3g} |" for s in summary.scenarios]
    notes = [(s.name, absent_note(s.out)) for s in summary.scenarios]
    if any(note for _, note in notes):
        parts += ["", "## Absent sensors", ""]
        parts += [f"- {name}: {note}; the plots leave gaps there." for name, note in notes if note]
    parts += ["", "## Timings", "", "| step | s |", "|---|---:|"]
    parts += [f"| {k} | {v:.1f} |" for k, v in summary.timings_s.items()]
    parts += ["", "## Plots", ""]
    for s in summary.scenarios:
        png = _plot_scenario(s, plots / f"{s.name}.png")
        parts += [f"### {s.name}", "", f"![{s.name}](plots/{png.name})", ""]
    path = out_dir / "report.md"
    path.write_text("\n".join(parts) + "\n")
    return path
