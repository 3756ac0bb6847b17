"""Human report of `imufmu diagnose`: report.md with PNG plots (residual over time, residual
against the selected effect, before/after)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _plots(out_dir: Path, plot_data) -> list[str]:
    """Write the three figures; return their file names."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from training.diagnosis.effect_readings import DISPLAY
    before, after, fit, prediction = plot_data
    target, name = fit.target, fit.label
    unit, scale = DISPLAY[target.split("_")[0]]
    res0, res1 = before.residual[target] * scale, after.residual[target] * scale
    effect = prediction * scale
    axis = int(np.nanargmax(np.nanvar(effect, axis=0)))
    t, held = before.t, before.holdout
    names = []
    fig, ax = plt.subplots(figsize=(9, 3.5))
    ax.plot(t, res0[:, axis], lw=0.5, label="residual")
    ax.plot(t, effect[:, axis], lw=1.0, label=f"fitted {name}")
    ax.set(xlabel="t [s]", ylabel=f"{target} residual, component {axis} [{unit}]", title="Residual over time")
    ax.legend(fontsize=8)
    fig.tight_layout(); fig.savefig(out_dir / "residual_time.png", dpi=90); plt.close(fig)
    names.append("residual_time.png")
    fig, ax = plt.subplots(figsize=(5, 4))
    sel = before.test
    ax.plot(effect[sel, axis], res0[sel, axis], ".", ms=1.5, alpha=0.4)
    lim = np.nanpercentile(np.abs(effect[sel, axis]), 99.5)
    ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8)
    ax.set(xlabel=f"selected regressors · fitted coefficients [{unit}]",
           ylabel=f"residual [{unit}]", title=f"Held-out residual vs {name}")
    fig.tight_layout(); fig.savefig(out_dir / "residual_vs_regressor.png", dpi=90); plt.close(fig)
    names.append("residual_vs_regressor.png")
    fig, ax = plt.subplots(figsize=(9, 3.5))
    ax.plot(t[held], res0[held, axis], ".", ms=1.0, label="before")
    ax.plot(t[held], res1[held, axis], ".", ms=1.0, label="after")
    ax.set(xlabel="t [s]", ylabel=f"residual [{unit}]", title="Held-out residual before / after")
    ax.legend(fontsize=8)
    fig.tight_layout(); fig.savefig(out_dir / "before_after.png", dpi=90); plt.close(fig)
    names.append("before_after.png")
    return names


def _limit_lines(limits: list[dict]) -> list[str]:
    """The detection-limit table of report.md (nothing when the diagnosis computed none)."""
    if not limits:
        return []
    from training.display import DISPLAY
    lines = ["## Detection limits (what the loop left)", "",
             "The smallest effect of each family that the loop would still select on these recordings: an "
             "effect of the family (every regressor contributing alike) added to the residual the loop left, "
             "and the selection's own fit and test repeated until it just passes (training.diagnosis.detection). "
             "It counts the held-out noise, the reference's own error, what the linear refit absorbs and how "
             "much the recordings excite the family. Held-out RMS of that effect, and its reading:", "",
             "| family | target | detection limit (held-out RMS) | reading at the limit |", "|---|---|---|---|"]
    for limit in limits:
        unit = DISPLAY[limit["target"].split("_")[0]][0]
        size = {"limit": f"{limit['rms']:.3g} {unit}" if limit["rms"] is not None else "",
                "present": "significant already (left by the loop's iteration or term limit)",
                "unreachable": "not detectable: the recordings do not excite it"}[limit["status"]]
        lines.append(f"| {limit['family']} | {limit['target']} | {size} | {limit['reading'] or '–'} |")
    return lines + [""]


def write_report(out_dir: Path, result: dict, plot_data=None) -> Path:
    """Write out_dir/report.md from the diagnosis.json document (and the figures when plot_data)."""
    out_dir = Path(out_dir)
    lines = ["# Diagnosis report", "",
             f"Recordings: {', '.join(r['name'] + ' (' + str(r['samples']) + ' samples)' for r in result['recordings'])}. "
             f"Model: `{result['model_in']}`. Held-out: {result['holdout']}; regression rows decimated to ≤ {result['regression_rate_hz']:.0f} Hz; significance: "
             f"{result['test']}, Bonferroni-corrected p < {result['alpha_bonferroni']}, and explained share "
             f"(of the residual left by the offset and the triad's linear calibration refitted alone) ≥ "
             f"{result['min_explained']:.0%}. Thermal model refitted: {result['thermal_refitted']}.", ""]
    if result["selected"] is None:
        lines += ["**Result: nothing significant left.**", "",
                  f"{result['metric']}: {result['before']:.4g} (unchanged).", ""]
    else:
        lines += [f"**Result: {result['conclusion']}.**", ""] + [f"- {x}" for x in result["selected"]["readings"]] + ["",
                  f"{result['metric']} on `{result['target']}`: before {result['before']:.4g}, after "
                  f"{result['after']:.4g} ({result['improvement_pct']:.1f} % lower).", "",
                  "| iteration | selected | target | regressors | explained | p (Bonferroni) | before | after | reading |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for k, it in enumerate(result["iterations"], 1):
            s = it["selected"]
            lines.append(f"| {k} | {s['name']} | {s['target']} | {', '.join(s['regressors'])} | "
                         f"{s['explained_fraction']:.1%} | {s['p_value']:.2g} | {it['before']:.4g} | "
                         f"{it['after']:.4g} | {'; '.join(s['readings'])} |")
        lines += [""] + [f"- iteration {k}: {it['selected'][key]}" for key in ("stage_note", "linear_refit_note")
                         for k, it in enumerate(result["iterations"], 1) if it["selected"].get(key)] + [""]
    lines += ["## Error per target, the whole loop", "", "| target | metric | before | after | lower |", "|---|---|---|---|---|"]
    for t, before in result["metrics_before"].items():
        after = result["metrics_after"][t]
        lower = f"{100.0 * (before - after) / before:.1f} %" if before > 0 else "–"
        lines.append(f"| {t} | {result['metric_names'][t]} | {before:.4g} | {after:.4g} | {lower} |")
    lines += [""] + _limit_lines(result["detection_limits"]) + [
        "## Candidates (first iteration, ranked by held-out explained share)", "",
        "| candidate | target | regressors | explained | p (Bonferroni) |", "|---|---|---|---|---|"]
    for c in result["candidates"][:25]:
        lines.append(f"| {c['name']} | {c['target']} | {', '.join(c['regressors'])} | {c['explained_fraction']:.1%} | "
                     f"{c['p_value']:.2g} |")
    if result["notes"]:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in result["notes"]]
    if plot_data is not None:
        lines += ["", "## Plots", ""] + [f"![{n}]({n})" for n in _plots(out_dir, plot_data)]
    path = out_dir / "report.md"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
