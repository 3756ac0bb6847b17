"""`imufmu noise` outputs: noise.json (the imufusion-noise/1 block), imu.yaml (Kalibr), one Allan
deviation plot per triad (allan_<triad>.png) and noise.md; and the summary lines train prints."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from training.noise.characterise import TRIADS, NoiseResult, characterise
from training.noise.kalibr import write_imu_yaml
from training.noise.plot import plot_triad

#: Names written in the output folder.
JSON_NAME, YAML_NAME, MD_NAME = "noise.json", "imu.yaml", "noise.md"
#: Figure labels of the summaries.
LABELS = {"noise_density": "N", "bias_instability": "B", "random_walk": "K"}


@dataclass(frozen=True)
class NoiseFolder:
    """What noise_to_folder wrote, with the result."""

    json: Path
    yaml: Path
    markdown: Path
    plots: list[Path]
    result: NoiseResult


def figure_text(f: dict) -> str:
    """'5.2e-05 [4.9e-05, 5.5e-05] rad/s/√Hz' or 'unsupported (why)'."""
    if f["supported"]:
        return f"{f['value']:.3g} [{f['ci'][0]:.3g}, {f['ci'][1]:.3g}] {f['unit']}"
    return f"— ({f['why']})"


def summary_lines(block: dict, compact: bool = False) -> list[str]:
    """Plain-text lines of the block: one per triad and figure (compact: one per triad, supported
    figures only, worst axis)."""
    lines = [f"noise (68 % CI; {block['still_seconds']:.1f} s still, longest {block['longest_still_seconds']:.1f} s "
             f"at {block['rate_hz']:.4g} Hz):"]
    for triad in TRIADS:
        entry = block["triads"].get(triad)
        if entry is None:
            continue
        if compact:
            parts = []
            for name, label in LABELS.items():
                figures = [a[name] for a in entry["axes"] if a[name]["supported"]]
                if figures:
                    worst = max(figures, key=lambda f: f["value"])
                    parts.append(f"{label} ≤ {worst['value']:.3g} {worst['unit']}")
                else:
                    parts.append(f"{label} unsupported")
            lines.append(f"  {triad}: " + ", ".join(parts))
            continue
        for name, label in LABELS.items():
            cells = "; ".join(f"{'xyz'[i]} {figure_text(a[name])}" for i, a in enumerate(entry["axes"]))
            lines.append(f"  {triad} {label}: {cells}")
        if entry["lsb"] is not None:
            lines.append(f"  {triad} lsb: {entry['lsb']:.4g} {entry['unit']}")
    return lines


def markdown_text(result: NoiseResult, plots: list[Path]) -> str:
    """noise.md: the source, a table per triad (value and 68 % CI per axis, or why not), the notes and plots."""
    block = result.block
    out = ["# Noise characterisation (Allan deviation)", "", f"Source: {block['source']}.", "",
           f"Rate {block['rate_hz']:.4g} Hz; still data {block['still_seconds']:.1f} s, longest still stretch "
           f"{block['longest_still_seconds']:.1f} s. Figures per IEEE 952 (N white noise density, B bias instability, "
           "K random walk) from the overlapping Allan deviation (allantools), 68 % confidence intervals; "
           "'—' = the data cannot support the figure (the reason follows).", ""]
    for triad, entry in block["triads"].items():
        out += [f"## {triad} [{entry['unit']}]", "", "| figure | x | y | z |", "|---|---|---|---|"]
        for name, label in LABELS.items():
            out.append(f"| {label} [{entry['axes'][0][name]['unit']}] | "
                       + " | ".join(figure_text(a[name]) for a in entry["axes"]) + " |")
        out += ["", f"Quantisation step: {entry['lsb']:.4g} {entry['unit']}." if entry["lsb"] is not None
                else "Quantisation step: none seen.", ""]
        for p in plots:
            if p.name == f"allan_{triad}.png":
                out += [f"![{triad} Allan deviation]({p.name})", ""]
    if result.notes:
        out += ["## Notes", ""] + [f"- {n}" for n in result.notes] + [""]
    return "\n".join(out)


def write_noise_outputs(result: NoiseResult, out_dir: str | Path) -> NoiseFolder:
    """Write noise.json, imu.yaml, allan_<triad>.png and noise.md of `result` into out_dir."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    json_path = out / JSON_NAME
    json_path.write_text(json.dumps({"noise": result.block}, indent=2, ensure_ascii=False, allow_nan=False) + "\n",
                         encoding="utf-8")
    yaml = write_imu_yaml(result.block, out / YAML_NAME)
    plots = [p for triad, axes in result.axes.items()
             if (p := plot_triad(triad, axes, out / f"allan_{triad}.png")) is not None]
    md = out / MD_NAME
    md.write_text(markdown_text(result, plots), encoding="utf-8")
    return NoiseFolder(json_path, yaml, md, plots, result)


def noise_to_folder(paths: list[str | Path], out_dir: str | Path, progress: bool = False) -> NoiseFolder:
    """`imufmu noise DATA... --out DIR`: read the recordings, characterise their still data (progress bar
    when asked and slow), write the outputs."""
    from training.data.io import read_imu_csv
    return write_noise_outputs(characterise([read_imu_csv(p) for p in paths], progress=progress), out_dir)


def main(argv: list[str] | None = None) -> int:
    """`python -m training.noise.report DATA...`: print noise.md's tables for the recordings (no files
    written; docs/noise.md's PAN table comes from here)."""
    import sys
    from training.data.io import read_imu_csv
    paths = sys.argv[1:] if argv is None else argv
    result = characterise([read_imu_csv(p) for p in paths])
    print(markdown_text(result, []))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
