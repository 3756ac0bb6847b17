"""Mode-0 ablation of the magnetometer particle filter (issue 18 item 2, docs/magpf.md "Mode 0
ablation"): prints one Markdown table.

    python benchmarks/magpf_ablation.py [--seeds 20] [--seconds 60] [--source-sweep]

Row 1 is the 9-state filter as its source describes it (training.models.magpf.SOURCE_METHOD:
issue 3 steps 1–8, every project addition off). Each following row adds one addition of
magpf.ADDITIONS to the row above (cumulative); the last of them is magpf.METHOD_WITH_ADDITIONS
(the "method + project additions" row of bench_magpf.py). Then the additions that row leaves off
(magpf.LATER_ADDITIONS, still cumulative), plain SIR (steps 5–6 off) without and with the
additions, the product's Rao-Blackwellised filter at its defaults and the batch ellipsoid fit.

Scenarios as in bench_magpf.simulated, all from the wide zero prior (magpf.zero_prior), C filter
(magpf.run_c), pf_seed = simulation seed: tumbling, figures at the end; hard-iron jump of 20 µT at
half the run, figures at the end (the ellipsoid is fitted on the samples after the jump). Figures
(bench_magpf.figures): hard-iron error (largest axis) at the end [µT] and RMS of |h_c| − |h_0| on
the noise-free distorted field over the last min(10 s, half the run) [%], mean / worst over the
seeds, and the seeds on which the filter declared a change of environment (on the tumbling record a
false one). `--source-sweep` prints the same table for the source's method at other values of its own
parameters (SOURCE_SWEEP) instead. `--seeds 2 --seconds 10` is the small input of
tests/test_magpf_ablation.py.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

import bench_magpf  # noqa: E402
from contract import layout  # noqa: E402
from training.models import magpf  # noqa: E402

#: Row labels of the filter variants -> settings overrides (zero prior added), in table order.
SOURCE_LABEL = "the source's method: 9-state, splitting + network (SOURCE_METHOD)"
RB_LABEL = "particle filter, Rao-Blackwellised (the product's mode, defaults)"
ELLIPSOID_LABEL = "ellipsoid fit (batch)"
#: Appended to the label of the row whose settings are METHOD_WITH_ADDITIONS.
WITH_ADDITIONS_SUFFIX = " = method + project additions (METHOD_WITH_ADDITIONS)"
FIELD_NORM_UT = 60.0
JUMP_UT = (20.0, 0.0, 0.0)


def variants() -> dict[str, dict]:
    """Label -> settings overrides of every filter row: the source's method, the additions added
    one at a time (cumulative), plain SIR without and with the additions, the Rao-Blackwellised mode."""
    rows = {SOURCE_LABEL: dict(magpf.SOURCE_METHOD)}
    current = dict(magpf.SOURCE_METHOD)
    for addition in magpf.ADDITIONS + magpf.LATER_ADDITIONS:
        current = {**current, **addition.on}
        suffix = WITH_ADDITIONS_SUFFIX if current == magpf.METHOD_WITH_ADDITIONS else ""
        rows[f"+ {addition.label}{suffix}"] = current
    rows["plain SIR: the source's method without steps 5–6 (its baseline)"] = {**magpf.SOURCE_METHOD, "enable_splitting": 0}
    rows["plain SIR with the additions (METHOD_WITH_ADDITIONS, steps 5–6 off)"] = {
        **magpf.METHOD_WITH_ADDITIONS, "enable_splitting": 0}
    rows[RB_LABEL] = {}
    return rows


_DEFAULTS = layout.settings_defaults()
#: The source's method at other values of its own parameters (--source-sweep): label -> overrides.
SOURCE_SWEEP = {
    "the source's method at the FMU defaults": {},
    f"  N {4 * int(_DEFAULTS['pf_particles'])}": {"pf_particles": 4 * int(_DEFAULTS["pf_particles"])},
    "  process noise 30×": {k: 30.0 * _DEFAULTS[k] for k in ("pf_process_noise_hard", "pf_process_noise_soft")},
    "  measurement noise σ 10×": {"pf_measurement_noise": 10.0 * _DEFAULTS["pf_measurement_noise"]},
    "  decimation 1 (an update every sample)": {"pf_decimation": 1},
}


def source_sweep() -> dict[str, dict]:
    """Label -> settings overrides of the source's method at other values of its parameters."""
    return {label: {**magpf.SOURCE_METHOD, **over} for label, over in SOURCE_SWEEP.items()}


def _run_filter(d: magpf.TumblingData, s: dict, end: int, tail_s: float) -> tuple[float, float, float, float]:
    """bench_magpf.figures of the C filter, then the number of changes declared by sample `end`."""
    r = magpf.run_c(d.mag, s)
    est = np.column_stack([r.hard_iron, r.soft_iron])
    fig = bench_magpf.figures(d, r.hard_iron[end - 1], lambda f, tail: magpf.apply(est[tail], f), end, tail_s)
    return (*fig, float(r.changes[end - 1]))


def ablation(seeds: int, seconds: float, rows: dict[str, dict | None] | None = None) -> dict[str, dict[str, np.ndarray]]:
    """label -> scenario ("tumbling", "jump") -> (seeds, 4): the figures of bench_magpf.figures
    (hard-iron error [µT], norm RMS clean [%], norm RMS measured [%]) and the changes of
    environment declared (NaN for the ellipsoid fit) of the rows (label ->
    settings overrides, None: the ellipsoid fit; default `variants` and the ellipsoid fit)."""
    tail_s = min(bench_magpf.TAIL_S, 0.5 * seconds)
    rows = {**variants(), ELLIPSOID_LABEL: None} if rows is None else rows
    out = {label: {"tumbling": [], "jump": []} for label in rows}
    for seed in range(seeds):
        for scenario, jump_at_s in (("tumbling", None), ("jump", 0.5 * seconds)):
            d = magpf.simulate_tumbling(seed, duration_s=seconds, jump_at_s=jump_at_s, jump_ut=JUMP_UT,
                                        field_norm_ut=FIELD_NORM_UT)
            end = len(d.mag)
            for label, over in rows.items():
                if over is None:
                    start = 0 if jump_at_s is None else int(round(jump_at_s * d.rate_hz))
                    fig = bench_magpf.run_ellipsoid(bench_magpf.after(d, start), end - start, tail_s)
                    fig = (*fig, float("nan"))
                else:
                    s = magpf.settings(FIELD_NORM_UT, pf_seed=seed, **{**magpf.zero_prior(FIELD_NORM_UT), **over})
                    fig = _run_filter(d, s, end, tail_s)
                out[label][scenario].append(fig)
    return {label: {k: np.array(v) for k, v in scen.items()} for label, scen in out.items()}


def markdown(result: dict[str, dict[str, np.ndarray]]) -> str:
    """The table: per scenario hard-iron error and clean norm RMS, mean / worst over the seeds,
    and the seeds on which a change of environment was declared (tumbling: none happened)."""
    lines = ["| configuration | tumbling: hard-iron err mean / worst [µT] | tumbling: norm RMS clean mean / worst [%] "
             "| jump: hard-iron err mean / worst [µT] | jump: norm RMS clean mean / worst [%] "
             "| seeds with a change declared: tumbling (false) / jump |",
             "|---|---|---|---|---|---|"]
    for label, scen in result.items():
        cells = [f"{a[:, c].mean():.3f} / {a[:, c].max():.3f}" for a in (scen["tumbling"], scen["jump"]) for c in (0, 1)]
        declared = [a[:, 3] for a in (scen["tumbling"], scen["jump"])]
        cells.append("—" if np.isnan(declared[0]).all() else " / ".join(str(int(np.sum(c > 0))) for c in declared))
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=20, help="simulation seeds (default 20)")
    p.add_argument("--seconds", type=float, default=60.0, help="length of each simulated run [s] (default 60)")
    p.add_argument("--source-sweep", action="store_true",
                   help="instead: the source's method at other values of its own parameters (SOURCE_SWEEP)")
    a = p.parse_args(argv)
    if a.seeds < 1 or not a.seconds >= 2.0:
        p.error("--seeds must be >= 1 and --seconds >= 2")
    title = "The source's method at other settings" if a.source_sweep else "Mode 0 ablation"
    print(f"### {title} ({a.seeds} seeds, {a.seconds:g} s, zero prior; jump of {JUMP_UT[0]:g} µT at "
          f"{0.5 * a.seconds:g} s)\n")
    print(markdown(ablation(a.seeds, a.seconds, source_sweep() if a.source_sweep else None)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
