"""OUT/fleet.json and OUT/fleet.md: the population of a fleet's calibrations, its outliers and the
units whose calibration failed (training.fleet.population)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from contract.layout import TRIAD_ORDER
from training.artefact import ModelArtefact, load_artefact
from training.fleet.population import (MIN_UNITS_FOR_OUTLIERS, OUTLIER_SIGMAS, POPULATION_TEMP_C, outliers,
                                       population, unit_parameters)
from training.fleet.train import UnitResult
from training.models.prior import MIN_PRIOR_UNITS, build_prior

#: Parameter kinds drawn as histograms, one figure per triad.
HISTOGRAM_KINDS = ("bias", "scale")
#: Format version of fleet.json.
FLEET_FORMAT = 1


def fleet_prior(artefacts: list[ModelArtefact]) -> dict[str, dict]:
    """fleet.json 'prior': per triad, the population of the full gain/bias fits against a reference
    (training.models.prior.build_prior), for `imufmu train --prior`."""
    out = {}
    for triad in TRIAD_ORDER:
        fits = [(a.thermal[triad], a.fit_stats[triad]) for a in artefacts
                if a.thermal[triad].enabled and a.fit_stats.get(triad, {}).get("reference", "none") != "none"
                and "rms_after" in a.fit_stats[triad] and not a.fit_stats[triad].get("bias_only")]
        prior = build_prior([m for m, _ in fits], [float(st["rms_after"]) for _, st in fits])
        if prior is not None:
            out[triad] = prior.to_json()
    return out


def fleet_elm_document(results: list[UnitResult], excluded: list[str], seed: int, progress: bool) -> dict:
    """fleet.json 'elm': the fleet ELM learnt from the non-outlier units' compass rows
    (training.models.fleet_elm), with a progress bar over its two fits."""
    from tqdm import tqdm
    from training.models.fleet_elm import fit_fleet_elm, fleet_elm_json
    from training.train import deterministic
    rows = {r.unit: r.elm_rows for r in results if r.model and r.unit not in excluded and r.elm_rows is not None}
    with deterministic(seed), tqdm(total=2, desc="fleet ELM (held-out check, fit)", unit="fit",
                                   disable=not progress or len(rows) < MIN_PRIOR_UNITS) as bar:
        return fleet_elm_json(*fit_fleet_elm(rows, seed, bar.update))


def fleet_document(results: list[UnitResult], out_dir: Path, seed: int = 0, progress: bool = False) -> dict:
    """The content of out_dir/fleet.json: per-unit status (models named relative to out_dir), the
    population, outliers, failures and the prior.
    The prior and the fleet ELM leave out every outlier unit (`prior_excludes`): one unit with a 10×
    bias would otherwise widen the population's σ for every new unit."""
    artefacts = {r.unit: load_artefact(r.model) for r in results if r.model}
    trained = {unit: unit_parameters(a) for unit, a in artefacts.items()}
    stats = population(trained)
    found = outliers(stats)
    excluded = sorted({o["unit"] for o in found})
    return {"format": "imufusion-fleet", "format_version": FLEET_FORMAT,
            "population_temperature_c": POPULATION_TEMP_C, "outlier_sigmas": OUTLIER_SIGMAS,
            "units": {r.unit: {k: v for k, v in r.summary(out_dir).items() if k != "unit"} for r in results},
            "trained": len(trained), "failed": [{"unit": r.unit, "reason": r.reason} for r in results if not r.model],
            "population": stats, "outliers": found, "prior_excludes": excluded,
            "prior": fleet_prior([a for unit, a in artefacts.items() if unit not in excluded]),
            "elm": fleet_elm_document(results, excluded, seed, progress)}


def _histograms(stats: dict, out_dir: Path) -> list[Path]:
    """One PNG per triad: a histogram of each bias and scale parameter over the units."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    paths = []
    for triad in TRIAD_ORDER:
        names = [n for n in stats if n.startswith(f"{triad}.") and n.split(".")[1].split("_")[0] in HISTOGRAM_KINDS]
        if not names:
            continue
        fig, axes = plt.subplots(2, 3, figsize=(11, 5.5))
        for ax, name in zip(axes.ravel(), names):
            s = stats[name]
            ax.hist(list(s["values"].values()), bins=30, color="tab:blue")
            ax.axvline(s["median"], color="k", lw=1)
            ax.set_xlabel(f"{name} [{s['unit']}]")
            ax.set_ylabel("units")
        fig.tight_layout()
        path = out_dir / f"fleet_{triad}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        paths.append(path)
    return paths


def _prior_lines(doc: dict) -> list[str]:
    """fleet.md's prior section: the triads it covers, the units left out, the fleet ELM."""
    triads = ", ".join(f"{t} ({p['units']} units)" for t, p in doc["prior"].items()) or "none"
    return [f"- Gain/bias populations: {triads}.",
            f"- Left out as outliers: {', '.join(doc['prior_excludes']) or 'none'}.",
            f"- {fleet_elm_summary(doc['elm'])}."]


def fleet_elm_summary(elm: dict) -> str:
    """One line on the fleet ELM of fleet.json 'elm': what it does on the held-out units, or why there is none."""
    if "model" not in elm:
        return f"No fleet ELM: {elm['reason']}"
    return (f"Fleet ELM: {elm['hidden']} nodes from {elm['units']} units; on the held-out units "
            f"{', '.join(elm['held_out_units'])} it moves the field error {elm['rms_before']:.3g} -> {elm['rms_after']:.3g} µT")


def _markdown(doc: dict, plots: list[Path]) -> str:
    """fleet.md from the fleet document."""
    lines = [f"# Fleet calibration: {len(doc['units'])} units, {doc['trained']} trained, {len(doc['failed'])} failed",
             "", f"Parameters of each unit's calibration at {doc['population_temperature_c']:g} °C (bias, scale "
             "factor − 1, cross-axis angle of the linear map the thermal model applies there).", "",
             "## Outliers", ""]
    if doc["trained"] < MIN_UNITS_FOR_OUTLIERS:
        lines.append(f"Not named: fewer than {MIN_UNITS_FOR_OUTLIERS} units trained.")
    elif not doc["outliers"]:
        lines.append(f"None: every parameter of every unit is within {doc['outlier_sigmas']:g} robust σ of the median.")
    else:
        lines += ["| unit | parameter | value | population median | distance [robust σ] |", "|---|---|---|---|---|"]
        lines += [f"| {o['unit']} | {o['parameter']} | {o['value']:.4g} {o['unit_of_value']} | {o['median']:.4g} | "
                  f"{o['distance']:.1f} |" for o in doc["outliers"]]
    lines += ["", "## Failed units", ""]
    lines += [f"- {f['unit']}: {f['reason']}" for f in doc["failed"]] or ["None."]
    lines += ["", "## Prior (`imufmu train DATA --prior fleet.json`)", ""] + _prior_lines(doc)
    lines += ["", "## Population", "", "| parameter | unit | units | mean | std | median | robust σ | 5 % | 95 % |",
              "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {n} | {s['unit']} | {s['units']} | {s['mean']:.4g} | {s['std']:.3g} | {s['median']:.4g} | "
              f"{s['robust_sigma']:.3g} | {s['p05']:.4g} | {s['p95']:.4g} |" for n, s in doc["population"].items()]
    lines += [""] + [f"![{p.stem}]({p.name})" for p in plots]
    return "\n".join(lines) + "\n"


def write_fleet_report(results: list[UnitResult], out_dir: str | Path, seed: int = 0,
                       progress: bool = False) -> tuple[Path, Path, dict]:
    """Write out_dir/fleet.json, fleet.md and the histograms; returns (json, md, document)."""
    out_dir = Path(out_dir)
    doc = fleet_document(results, out_dir, seed, progress)
    plots = _histograms(doc["population"], out_dir) if doc["trained"] else []
    json_path, md_path = out_dir / "fleet.json", out_dir / "fleet.md"
    json_path.write_text(json.dumps(doc, indent=1, default=lambda v: float(v) if isinstance(v, np.floating) else v) + "\n")
    md_path.write_text(_markdown(doc, plots))
    return json_path, md_path, doc
