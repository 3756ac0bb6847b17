"""Does the user calibration protocol (scenarios/protocol.toml, docs/calibration.md) pin the
sensor down as well as the lab calibration set (scenarios/calibration.toml)? Prints Markdown.

    python benchmarks/bench_protocol.py [--seeds 0 1 2] [--no-check] [--no-eval] [--selfcal] [--per-seed]

1. Checks of the protocol recording (simulated with the first seed): duration and structure
   per segment, temperature range against the evaluation scenarios, rest windows found in the
   raw signals, distinct gravity directions among them (greedy clusters > 15° apart), consecutive
   rest pairs joined by a rotation (what the gyro gain fit uses), and coverage of the 26
   direction cells (cube faces, edges, corners) by the true body-frame field during the tumbles.
2. For each seed s: simulate protocol.toml and calibration.toml with seed s, train each WITH its
   reference columns (training.train.train, as the main job does), simulate eval_handheld and
   eval_figure8 with seeds s+1 and s+2 (as training.main_job does), run the batch runtime with
   the settings train wrote ("as trained") and the method's Euler fusion set by hand,
   and compute training.evaluate.compute_metrics. Table: mean over seeds (worst in brackets when
   more than one seed), acceptance bounds of the main job and the uncompensated sensors below.
   --selfcal adds the protocol trained WITHOUT its truth columns (self-calibration from the
   invariants, as a user's recording is); --per-seed prints one table per seed as well.
"""
from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np

from contract import layout
from training.artefact import coefficients_array, settings_dict
from training.evaluate import ACCEPTANCE, compute_metrics, raw_sensor_metrics
from training.main_job import recording_parameters, settings_with
from training.runtime import run_batch
from training.simulator import load_scenario, simulate

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
TRAINING_SETS = ("protocol.toml", "calibration.toml")
EVALUATIONS = ("eval_handheld.toml", "eval_figure8.toml")
#: Runtime settings: as `train` wrote them (the FMU defaults plus the trained values), and the
#: method's adaptive-gain Euler fusion set by hand for comparison.
CONFIGS = {"as trained": {},
           "attitude_mode 0, no rest bias (hand-set)": {"attitude_mode": 0.0, "rest_gyro_threshold": 0.0}}
COLUMNS = (("rate_err_dps", "rate [°/s]", 4), ("field_err_ut", "field [µT]", 3),
           ("roll_err_deg", "roll [°]", 3), ("pitch_err_deg", "pitch [°]", 3),
           ("yaw_err_deg", "yaw [°]", 3), ("tilt_err_deg", "tilt [°]", 3),
           ("heading_err_deg", "heading [°]", 3))

#: A positions segment whose holds are shorter than this [s] is a continuous tour (a tumble).
MIN_REST_S = 1.5
# Field-direction coverage: a cell counts when the true field points into it for this long.
CELL_MIN_S = 0.2


# ----------------------------------------------------------------------------- checks

def rest_windows(data) -> list:
    """The rests the self-calibration finds in the raw signals (training.selfcal.rest), with poses."""
    from training.selfcal.poses import group_poses
    from training.selfcal.rest import detect_rest
    return group_poses(list(detect_rest(data).windows))


def pose_directions(windows) -> np.ndarray:
    """(P, 3) mean gravity ('down') direction of each pose of the windows."""
    down = {}
    for w in windows:
        if w.pose >= 0:
            down.setdefault(w.pose, []).append(-w.acc / np.linalg.norm(w.acc))
    centres = np.array([np.mean(v, axis=0) for v in down.values()])
    return centres / np.linalg.norm(centres, axis=1, keepdims=True)


def cell_directions() -> np.ndarray:
    """The 26 unit directions of a cube's faces, edges and corners."""
    v = np.array([p for p in itertools.product((-1, 0, 1), repeat=3) if any(p)], dtype=float)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def covered_cells(field: np.ndarray, rate_hz: float) -> int:
    """Cells (of 26) the field direction points into (nearest cell) for at least CELL_MIN_S."""
    cells = cell_directions()
    u = field / np.linalg.norm(field, axis=1, keepdims=True)
    counts = np.bincount(np.argmax(u @ cells.T, axis=1), minlength=len(cells))
    return int(np.sum(counts >= CELL_MIN_S * rate_hz))


def segment_spans(scenario) -> list[tuple[str, float, float]]:
    """(kind, start [s], end [s]) of each segment; kind is the segment type, except that a
    positions segment whose holds are shorter than MIN_REST_S is a "tumble" (a continuous tour)
    and a handheld segment is a "tumble" too."""
    spans, t = [], 0.0
    for s in scenario.segments:
        kind = type(s).__name__.lower()
        if kind == "handheld" or (kind == "positions" and s.hold_s < MIN_REST_S):
            kind = "tumble"
        spans.append((kind, t, t + s.duration_s))
        t += s.duration_s
    return spans


def rotation_deg(q1: np.ndarray, q2: np.ndarray) -> float:
    """Angle of the rotation between two attitudes (4,) [deg]."""
    return float(np.degrees(2.0 * np.arccos(min(1.0, abs(float(np.dot(q1, q2)))))))


def check_protocol(seed: int) -> None:
    """Print the structure, temperature, pose and coverage checks of protocol.toml."""
    scenario = load_scenario(SCENARIOS / "protocol.toml")
    data = simulate(scenario, seed=seed)
    rate = scenario.rate_hz
    spans = segment_spans(scenario)
    print(f"\n## protocol.toml (seed {seed}): {scenario.duration_s:.1f} s = "
          f"{scenario.duration_s / 60:.2f} min, {len(data)} samples at {rate:g} Hz\n")
    print("| # | segment | start [s] | length [s] | temperature [°C] |")
    print("|---|---|---|---|---|")
    for k, (kind, a, b) in enumerate(spans):
        sel = (data.t >= a) & (data.t < b)
        print(f"| {k + 1} | {kind} | {a:.1f} | {b - a:.1f} | "
              f"{data.temp[sel].min():.1f} .. {data.temp[sel].max():.1f} |")
    rate_c = np.gradient(data.temp, data.t) * 60.0
    print(f"\nTemperature: {data.temp.min():.1f} .. {data.temp.max():.1f} °C, warming rate "
          f"{rate_c.min():.1f} .. {rate_c.max():.1f} °C/min. Evaluations: "
          + ", ".join(f"{n.removesuffix('.toml')} {e.temp.min():.1f} .. {e.temp.max():.1f} °C"
                      for n in EVALUATIONS for e in [simulate(load_scenario(SCENARIOS / n),
                                                              seed=seed + 1)]))

    rests = rest_windows(data)
    windows = [(w.start, w.stop) for w in rests]
    centres = pose_directions(rests)
    sep = np.degrees(np.arccos(np.clip(centres @ centres.T, -1, 1)))
    np.fill_diagonal(sep, 180.0)
    lengths = np.array([(b - a) / rate for a, b in windows])
    pairs = list(zip(windows[:-1], windows[1:]))
    rotations = np.array([rotation_deg(data.ref_q[b1 - 1], data.ref_q[a2]) for (_, b1), (a2, _) in pairs])
    swept = np.array([np.degrees(np.sum(np.linalg.norm(data.ref_gyr[b1:a2], axis=1))) / rate
                      for (_, b1), (a2, _) in pairs])
    print(f"\nRest windows (training.selfcal.rest, as the self-calibration finds them): {len(windows)}, "
          f"{lengths.sum():.0f} s in all ({lengths.min():.1f} .. {lengths.max():.1f} s each), "
          f"at {data.temp[[a for a, _ in windows]].min():.1f} .. "
          f"{data.temp[[a for a, _ in windows]].max():.1f} °C.")
    print(f"Distinct gravity directions (poses of training.selfcal.rest): {len(centres)}; "
          f"closest pair {sep.min():.1f}° apart.")
    blocks = [(a, b) for kind, a, b in spans if kind == "positions"]
    for k, (a, b) in enumerate(blocks):
        inside = [w for w in rests if w.start / rate < b and w.stop / rate > a]
        print(f"  block {k + 1}: {len(inside)} rests in the pose set, "
              f"{len({w.pose for w in inside if w.pose >= 0})} distinct directions")
    turned, full = rotations > 10.0, (rotations <= 10.0) & (swept > 300.0)
    print(f"Consecutive rest pairs (the gyro gain fit's data): {len(pairs)}; {int(turned.sum())} with "
          f"a net rotation of {rotations[turned].min():.0f} .. {rotations[turned].max():.0f}°, "
          f"{int(full.sum())} full turns (net 0°, {swept[full].min():.0f} .. {swept[full].max():.0f}° "
          f"turned), {len(pairs) - int(turned.sum()) - int(full.sum())} others.")

    tumbles = [(a, b) for kind, a, b in spans if kind == "tumble"]
    print(f"\nField-direction coverage (true body-frame field, nearest of 26 cells, >= "
          f"{CELL_MIN_S} s):")
    union = np.zeros(len(data), bool)
    for k, (a, b) in enumerate(tumbles):
        sel = (data.t >= a) & (data.t < b)
        union |= sel
        print(f"  tumble {k + 1} ({b - a:.0f} s): {covered_cells(data.ref_mag[sel], rate)}/26")
    print(f"  all tumbles: {covered_cells(data.ref_mag[union], rate)}/26; whole recording: "
          f"{covered_cells(data.ref_mag, rate)}/26; gravity, whole recording: "
          f"{covered_cells(-data.ref_acc, rate)}/26")


# ----------------------------------------------------------------------------- evaluation

def without_reference(data):
    """A copy of a simulated recording without its truth columns, as a user's recording is:
    `train` then self-calibrates from the invariants."""
    d = data.slice(slice(None))
    d.ref_q = d.ref_gyr = d.ref_acc = d.ref_mag = None
    d.meta["reference"] = "none"
    return d


def training_runs(selfcal: bool) -> list[tuple[str, str, bool]]:
    """(label, scenario file, drop the truth) of each training set."""
    runs = [(n.removesuffix(".toml"), n, False) for n in TRAINING_SETS]
    if selfcal:
        runs.insert(1, ("protocol, self-calibration", "protocol.toml", True))
    return runs


def print_table(title: str, results: dict, raw: dict | None, show_worst: bool) -> None:
    """One Markdown table: a row per (evaluation, training set, settings)."""
    print(f"\n## {title}\n")
    print("| evaluation | trained on | settings | " + " | ".join(c[1] for c in COLUMNS) + " |")
    print("|---|---|---|" + "---|" * len(COLUMNS))
    for (ev, label, config), rows in sorted(results.items(), key=lambda kv: kv[0][0], reverse=True):
        cells = []
        for key, _, digits in COLUMNS:
            v = np.array([r[key] for r in rows])
            cells.append(f"{v.mean():.{digits}f}" + (f" [{v.max():.{digits}f}]" if show_worst else ""))
        print(f"| {ev} | {label} | {config} | " + " | ".join(cells) + " |")
    for ev, rows in (raw or {}).items():
        cells = [f"{np.mean([r[k] for r in rows]):.{d}f}" if k in rows[0] else "—" for k, _, d in COLUMNS]
        print(f"| {ev} | uncompensated sensors | — | " + " | ".join(cells) + " |")
    print("| acceptance (main job) | | | "
          + " | ".join(f"{ACCEPTANCE[k]:g}" if k in ACCEPTANCE else "—" for k, _, _ in COLUMNS) + " |")


def evaluate(seeds: list[int], selfcal: bool, per_seed: bool) -> None:
    """Train on each training set, evaluate on the held-out scenarios; print the table(s)."""
    from training.train import train
    results: dict[tuple[str, str, str], list[dict]] = {}
    raw: dict[str, list[dict]] = {}
    for seed in seeds:
        evals = [simulate(load_scenario(SCENARIOS / n), seed=seed + 1 + k)
                 for k, n in enumerate(EVALUATIONS)]
        for e in evals:
            raw.setdefault(e.name, []).append(raw_sensor_metrics(e))
        for label, name, drop in training_runs(selfcal):
            clock = time.perf_counter()
            cal = simulate(load_scenario(SCENARIOS / name), seed=seed)
            artefact = train([without_reference(cal) if drop else cal], seed=seed, progress=False)
            coefficients = coefficients_array(artefact)
            base = np.asarray(layout.settings_array(settings_dict(artefact)))
            on = {k: "on" if artefact.settings.get(f"enable_{k}") else "off" for k in ("elm", "psobp")}
            print(f"  seed {seed}: trained on {label} ({len(cal) / cal.meta['rate_hz']:.0f} s, "
                  f"{cal.temp.min():.0f}..{cal.temp.max():.0f} °C) in "
                  f"{time.perf_counter() - clock:.0f} s; ELM {on['elm']}, PSO-BP {on['psobp']}")
            for e in evals:
                for config, overrides in CONFIGS.items():
                    s = settings_with(base, {**recording_parameters(e), **overrides})
                    out = run_batch(coefficients, s, e.t, e.inputs())
                    results.setdefault((e.name, label, config), []).append(
                        compute_metrics(out, e).as_dict())
    if per_seed:
        for k, seed in enumerate(seeds):
            print_table(f"Seed {seed} (evaluations simulated with seeds {seed + 1}, {seed + 2})",
                        {key: [rows[k]] for key, rows in results.items()}, None, False)
    print_table(f"Held-out evaluation (seeds {seeds}; mean{' [worst]' if len(seeds) > 1 else ''})",
                results, raw, len(seeds) > 1)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2],
                   help="simulation / training seeds (default 0 1 2)")
    p.add_argument("--no-check", action="store_true", help="skip the recording checks")
    p.add_argument("--no-eval", action="store_true", help="skip the training and evaluation")
    p.add_argument("--selfcal", action="store_true",
                   help="also train on the protocol without its truth columns (self-calibration)")
    p.add_argument("--per-seed", action="store_true", help="also print one table per seed")
    args = p.parse_args()
    if not args.no_check:
        check_protocol(args.seeds[0])
    if not args.no_eval:
        evaluate(args.seeds, args.selfcal, args.per_seed)


if __name__ == "__main__":
    main()
