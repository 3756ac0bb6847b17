"""DIR/campaign.json, DIR/runs.csv and DIR/campaign.md: a Monte-Carlo campaign's runs, the
percentiles of every error and their histograms (training.fleet.campaign)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from training.fleet.campaign import CAMPAIGN_METRICS, Variation

#: The files `campaign` writes into its folder.
OUTPUT_FILES = ("campaign.json", "runs.csv", "campaign.png", "campaign.md")
#: Percentiles of the campaign table [%].
PERCENTILES = (5, 50, 95, 99)


def percentile_rows(runs: list[dict]) -> list[dict]:
    """Per metric: name, runs with a value, the PERCENTILES and the maximum."""
    rows = []
    for metric in CAMPAIGN_METRICS:
        values = np.array([r[metric] for r in runs], dtype=float)
        values = values[np.isfinite(values)]
        if values.size:
            rows.append({"metric": metric, "runs": int(values.size),
                         **{f"p{p}": float(np.percentile(values, p)) for p in PERCENTILES}, "max": float(values.max())})
    return rows


def failed_runs(runs: list[dict]) -> list[dict]:
    """The runs that failed (their 'failed' reason is not empty)."""
    return [r for r in runs if r.get("failed")]


def missing_notes(runs: list[dict], rows: list[dict]) -> list[str]:
    """Lines saying which errors have no row (no run has a value: the recording has no reference for
    them) and which runs failed, with the first reasons."""
    shown = {r["metric"] for r in rows}
    notes = [f"- {m}: no run has a value (the recording has no reference for it)" for m in CAMPAIGN_METRICS
             if m not in shown]
    failed = failed_runs(runs)
    if failed:
        notes.append(f"- {len(failed)} of {len(runs)} runs failed and are left out of the table; the first: "
                     + "; ".join(f"run {r['run']}: {r['failed']}" for r in failed[:3]))
    return notes or ["Every run gave every error."]


def _histograms(runs: list[dict], rows: list[dict], path: Path) -> Path:
    """One PNG with a histogram per metric."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 4, figsize=(13, 5.5))
    for ax, row in zip(axes.ravel(), rows):
        ax.hist([r[row["metric"]] for r in runs if np.isfinite(r[row["metric"]])], bins=40, color="tab:blue")
        ax.axvline(row["p95"], color="k", lw=1, ls="--")
        ax.set_xlabel(row["metric"])
        ax.set_ylabel("runs")
    for ax in axes.ravel()[len(rows):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def write_campaign_report(runs: list[dict], variations: tuple[Variation, ...], fmu_path, data_path, seed: int,
                          out_dir: str | Path, sensor_path=None) -> Path:
    """Write the campaign's files into out_dir; returns the path of campaign.md. `sensor_path`: the virtual-sensor
    FMU of a closed-loop campaign (campaign --sensor)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = percentile_rows(runs)
    (out_dir / OUTPUT_FILES[0]).write_text(json.dumps(
        {"fmu": str(fmu_path), "data": str(data_path), "sensor": None if sensor_path is None else str(sensor_path),
         "seed": seed, "runs": len(runs),
         "variations": [v.text() for v in variations], "percentiles": rows, "results": runs}, indent=1) + "\n")
    with open(out_dir / OUTPUT_FILES[1], "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(runs[0]))
        writer.writeheader()
        writer.writerows(runs)
    plot = _histograms(runs, rows, out_dir / OUTPUT_FILES[2])
    lines = [f"# Campaign: {len(runs)} runs of {Path(fmu_path).name} on {Path(data_path).name}", "",
             f"Seed {seed}; variations: " + (", ".join(f"`{v.text()}`" for v in variations) or "none") + ".", "",
             *([] if sensor_path is None else [
                 f"Closed loop: the recording's truth through the virtual sensor {Path(sensor_path).name}, its outputs "
                 f"through {Path(fmu_path).name} (the sensor's noise seed: each run's own draw, column `seed`, unless "
                 "varied).", ""]),
             "| error | runs | " + " | ".join(f"{p} %" for p in PERCENTILES) + " | max |",
             "|---|---|" + "---|" * (len(PERCENTILES) + 1)]
    lines += [f"| {r['metric']} | {r['runs']} | " + " | ".join(f"{r[f'p{p}']:.4g}" for p in PERCENTILES)
              + f" | {r['max']:.4g} |" for r in rows]
    lines += ["", *missing_notes(runs, rows)]
    lines += ["", f"![histograms]({plot.name})", "", "Every run: runs.csv and campaign.json."]
    md = out_dir / OUTPUT_FILES[3]
    md.write_text("\n".join(lines) + "\n")
    return md
