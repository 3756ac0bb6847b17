"""The virtual sensor's recording against the unit's own (issue 34's acceptance; docs/virtual_sensor.md; the
round trip through the ImuFusion FMU is training/sensor/closed_loop_bench.py's).

A static hour of the main job's unit simulated (scenarios/sensors/mems_grade.toml
at 25 °C) and the same truth through the virtual sensor of the trained model with the noise characterised from
that hour (training.noise). Per gyro and accelerometer axis: the residual (raw − the noise-free sensor output
of the truth) — its mean, with the 95 % interval of a mean over the hour from the characterised figures
(`mean_halfwidth`; the noise-free residual's mean is 0, so each recording's mean should lie within it), and
its overlapping Allan deviation at octave τ with allantools' χ² intervals (edf of the
noise type the local slope shows) — for the unit and the virtual sensor.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/virtual_sensor.py [--main-job DIR] [--hours 1]

--main-job: an `imufmu pipeline --out DIR` folder (default: run the main job into a temporary folder first).
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import allantools
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contract.sensor_variables import AXES  # noqa: E402
from fmu.cosim import run_named  # noqa: E402
from training.noise.allan import allan_curve  # noqa: E402
from training.noise.characterise import characterise  # noqa: E402
from training.sensor.build import build_sensor_fmu, noise_plan  # noqa: E402
from training.simulator.scenario import load_scenario  # noqa: E402
from training.simulator.simulate import simulate  # noqa: E402

#: The triads compared (the magnetometer's noise is the same construction) and the 95 % factor.
TRIADS = ("gyr", "acc")
Z95 = 1.959963984540054
UNIT_SCALE = {"gyr": (180.0 / math.pi, "°/s"), "acc": (1.0, "m/s²")}
RAW = tuple(f"{s}_{a}" for s in ("gyr", "acc", "mag") for a in AXES)


def main_job(folder: str | None) -> Path:
    """The main job's output folder: the given one, or a fresh run of `imufmu pipeline` (26 s)."""
    if folder:
        return Path(folder)
    out = Path(tempfile.mkdtemp(prefix="virtual-sensor-")) / "main_job"
    subprocess.run([sys.executable, "-m", "training.cli", "pipeline", "--out", str(out)], check=True, cwd=ROOT,
                   stdout=subprocess.DEVNULL)
    return out


STATIC_SCENARIO = """sensor = "{sensor}"
[scenario]
name = "static_hour"
rate_hz = 100.0
seed = 21
notes = "The main job's unit at rest and level at 25 degC (benchmarks/virtual_sensor.py)."
[earth_field]
norm_ut = 50.0
dip_deg = 60.0
declination_deg = 3.0
[start]
attitude_deg = [0.0, 0.0, 0.0]
temp_c = 25.0
warmup_rise_c = 0.0
[[segment]]
type = "hold"
duration_s = {duration}
"""


def static_unit(hours: float, folder: Path):
    """The main job's unit simulated at rest for `hours` (its own static recording, sidecar reference static)."""
    path = folder / "static_hour.toml"
    path.write_text(STATIC_SCENARIO.format(sensor=(ROOT / "scenarios" / "sensors" / "mems_grade.toml").as_posix(),
                                           duration=3600.0 * hours))
    data = simulate(load_scenario(path))
    data.meta["reference"] = "static"
    return data


def truth_inputs(data) -> dict[str, np.ndarray]:
    """The sensor FMU's inputs from a simulated recording's truth (body field given directly)."""
    inputs = {f"true_{name}_{a}": getattr(data, ref)[:, i] for name, ref in (("rate", "ref_gyr"), ("accel", "ref_acc"),
                                                                             ("field", "ref_mag"))
              for i, a in enumerate(AXES)}
    inputs["true_temp"] = data.temp
    return inputs


def alpha_of(avar: np.ndarray, taus: np.ndarray) -> np.ndarray:
    """The power-law noise exponent per τ from the local slope of the Allan variance: slope -1 white (α 0), 0
    flicker (-1), +1 random walk (-2)."""
    slope = np.gradient(np.log(avar), np.log(taus))
    return np.clip(np.round(-1.0 - slope), -2, 0).astype(int)


def allan_with_intervals(e: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Octave τ, overlapping Allan deviation and its 95 % interval (allantools' χ² interval, edf_greenhall)."""
    taus, dev, _, _ = allantools.oadev(e, rate=rate, data_type="freq", taus="octave")
    keep = taus * rate * 9 <= e.size
    taus, dev = taus[keep], dev[keep]
    alphas = alpha_of(dev ** 2, taus)
    lo, hi = np.empty_like(dev), np.empty_like(dev)
    for j, (tau, d, a) in enumerate(zip(taus, dev, alphas)):
        m = int(round(tau * rate))
        edf = allantools.edf_greenhall(alpha=int(a), d=2, m=m, N=e.size, overlapping=True, modified=False)
        lo[j], hi[j] = allantools.confidence_interval(d, edf, ci=0.95)
    return taus, dev, lo, hi


def mean_halfwidth(figures: dict[str, float], triad: str, axis: int, span_s: float) -> float:
    """The 95 % half-width of the mean of a residual over span_s [s] from the characterised figures (the same for
    the unit and its virtual sensor): Var = N²/T + (2 ln2/π) B² + K² T/3 (for white noise and a random walk from
    0 the variance of a mean over T is σ_A²(T) exactly; for the flicker floor an approximation)."""
    n, b, k = (figures.get(f"{triad}_{name}_{AXES[axis]}", 0.0)
               for name in ("noise_density", "bias_instability", "random_walk"))
    return Z95 * math.sqrt(n * n / span_s + 2.0 * math.log(2.0) / math.pi * b * b + k * k * span_s / 3.0)


def indistinguishable(job: Path, hours: float, folder: Path) -> list[dict]:
    """Part B rows: per gyro and accelerometer axis, the unit's and the virtual sensor's residual mean (± 95 %)
    and Allan deviations (the τ where each lies inside the other's 95 % interval)."""
    unit = static_unit(hours, folder)
    noise = characterise([unit])
    plan = noise_plan(noise.block)
    noise_figures = {name: axis[figure]["value"] for triad, entry in noise.block["triads"].items()
                     for a, axis in enumerate(entry["axes"]) for figure in ("noise_density", "bias_instability", "random_walk")
                     for name in [f"{triad}_{figure}_{AXES[a]}"] if axis[figure]["supported"]}
    sensor, _ = build_sensor_fmu(job / "model" / "model.json", folder / "ImuSensor_static.fmu",
                                 overrides=plan.parameters)
    print(f"static {hours:g} h of the unit: noise {noise.block['source']}")
    t = unit.t - unit.t[0]
    inputs = truth_inputs(unit)
    clean = run_named(sensor, t, inputs, RAW, {"noise": False, "field_from_attitude": False})
    virtual = run_named(sensor, t, inputs, RAW, {"seed": 5, "field_from_attitude": False})
    rate = 1.0 / float(np.median(np.diff(t)))
    rows = []
    for k, triad in enumerate(TRIADS):
        scale, unit_name = UNIT_SCALE[triad]
        measured = getattr(unit, triad)
        for i, axis in enumerate(AXES):
            e_unit = measured[:, i] - clean[:, 3 * k + i]
            e_virtual = virtual[:, 3 * k + i] - clean[:, 3 * k + i]
            mu, mv = float(e_unit.mean()), float(e_virtual.mean())
            wu = wv = mean_halfwidth(noise_figures, triad, i, t[-1] - t[0])
            tu, du, lu, hu = allan_with_intervals(e_unit, rate)
            tv, dv, lv, hv = allan_with_intervals(e_virtual, rate)
            inside_v = int(np.sum((dv >= lu) & (dv <= hu)))
            inside_u = int(np.sum((du >= lv) & (du <= hv)))
            rows.append({"axis": f"{triad} {axis}", "unit": unit_name, "mean_unit": mu * scale,
                         "mean_unit_ci": wu * scale, "mean_virtual": mv * scale, "mean_virtual_ci": wv * scale,
                         "mean_agrees": abs(mu) <= wu and abs(mv) <= wv,
                         "taus": len(tu), "virtual_in_unit_ci": inside_v, "unit_in_virtual_ci": inside_u,
                         "overlap": int(np.sum((lv <= hu) & (lu <= hv))),
                         "adev_1s_unit": float(np.interp(1.0, tu, du)) * scale,
                         "adev_1s_virtual": float(np.interp(1.0, tv, dv)) * scale,
                         "adev_min_unit": float(du.min()) * scale, "adev_min_virtual": float(dv.min()) * scale})
    return rows


def print_indistinguishable(rows: list[dict]) -> None:
    print("\n| axis | residual mean, unit (± 95 %) | residual mean, virtual (± 95 %) | both within their 95 % | "
          "Allan τ: 95 % intervals overlap | virtual in unit's 95 % · unit in virtual's | σ_A(1 s) unit / virtual | "
          "min σ_A unit / virtual |")
    print("|---|---:|---:|:-:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['axis']} [{r['unit']}] | {r['mean_unit']:.3g} ± {r['mean_unit_ci']:.2g} | "
              f"{r['mean_virtual']:.3g} ± {r['mean_virtual_ci']:.2g} | {'yes' if r['mean_agrees'] else 'no'} | "
              f"{r['overlap']}/{r['taus']} | {r['virtual_in_unit_ci']}/{r['taus']} · {r['unit_in_virtual_ci']}/{r['taus']} | "
              f"{r['adev_1s_unit']:.3g} / {r['adev_1s_virtual']:.3g} | {r['adev_min_unit']:.3g} / {r['adev_min_virtual']:.3g} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--main-job", help="an `imufmu pipeline --out` folder (default: run it first)")
    parser.add_argument("--hours", type=float, default=1.0, help="length of the unit's static recording [h]")
    args = parser.parse_args()
    job = main_job(args.main_job)
    with tempfile.TemporaryDirectory(prefix="virtual-sensor-static-") as tmp:
        print_indistinguishable(indistinguishable(job, args.hours, Path(tmp)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
