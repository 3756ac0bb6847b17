"""Simulate a scenario into an ImuData recording with the complete truth."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from training.data.dataset import ImuData
from training.data.earth import gravity_ned
from training.data.io import write_imu_csv
from training.frames import make_continuous, quat_from_euler, rotate_to_body
from training.simulator.scenario import Scenario, load_scenario
from training.simulator.trajectory import Chain, Motion

#: Tolerance when counting samples in the scenario duration (duration · rate is usually an
#: integer that floating point may miss by a few ulps).
SAMPLE_COUNT_TOLERANCE = 1e-6


def build_motion(scenario: Scenario, seed: np.random.SeedSequence) -> Motion:
    """Chain the segments, each starting at the attitude the previous one ended at; segment i
    draws its random choices from the i-th stream spawned from `seed`."""
    attitude = quat_from_euler(scenario.start_attitude)
    parts: list[Motion] = []
    for segment, stream in zip(scenario.segments, seed.spawn(len(scenario.segments))):
        motion = segment.build(attitude, np.random.default_rng(stream))
        attitude = motion.end_attitude()
        parts.append(motion)
    return Chain(parts)


def sample_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """Sample instants k / rate_hz [s] for 0 ≤ t < duration_s, shape (N,)."""
    count = int(np.floor(duration_s * rate_hz + SAMPLE_COUNT_TOLERANCE))
    return np.arange(count) / rate_hz


def simulate(scenario: Scenario, seed: int | None = None) -> ImuData:
    """Simulate `scenario` with `seed` (None: the scenario's own seed).

    The seed drives everything random — the handheld trajectories and the sensor noise —
    through independent streams (numpy SeedSequence.spawn), so the same seed gives
    bit-identical arrays. Truth: ref_q body -> NED (true north), ref_gyr [rad/s], ref_acc
    specific force f_b = R_nbᵀ (a_n − g_n) [m/s²] (g_n = [0, 0, scenario.gravity]), ref_mag = R_nbᵀ m_n [µT] before any sensor
    error; temp is the true sensor temperature (the temperature channel is error-free).
    eval_mask is all True: the truth is exact from the first sample, no settling is needed.
    """
    seed = scenario.seed if seed is None else int(seed)
    motion_seed, sensor_seed = np.random.SeedSequence(seed).spawn(2)
    t = sample_times(scenario.duration_s, scenario.rate_hz)
    truth = build_motion(scenario, motion_seed).sample(t)
    q = make_continuous(truth.q)
    ref_acc = rotate_to_body(q, truth.acc_nav - gravity_ned(scenario.gravity))
    ref_mag = rotate_to_body(q, scenario.earth.field_ned())
    temp, temp_rate = scenario.temperature_profile().evaluate(t)
    gyr, acc, mag = scenario.sensor.measure(truth.rate, ref_acc, ref_mag, temp, temp_rate,
                                            scenario.rate_hz, sensor_seed)
    data = ImuData(t=t, gyr=gyr, acc=acc, mag=mag, temp=temp, ref_q=q, ref_gyr=truth.rate,
                   ref_acc=ref_acc, ref_mag=ref_mag, eval_mask=np.ones(t.shape[0], dtype=bool),
                   meta=_meta(scenario, seed), name=scenario.name)
    data.validate()
    return data


def _meta(scenario: Scenario, seed: int) -> dict:
    """The imu-csv/1 sidecar of a simulated recording."""
    notes = ("Simulated; ref_* columns are exact truth (ref_q body -> NED, true north); temp is "
             "the true sensor temperature; eval_mask is 1 everywhere.")
    return {"format": "imu-csv/1", "rate_hz": scenario.rate_hz, "sensor": scenario.sensor.name,
            "reference": "simulated", "earth_field": scenario.earth.as_meta(),
            **({"gravity_mps2": scenario.gravity_mps2} if scenario.gravity_mps2 is not None else {}),
            "source": f"ImuFusion simulator {scenario.name}, seed {seed}", "license": "MIT",
            "notes": f"{scenario.notes} {notes}".strip()}


def simulate_to_dir(scenario_path: str | Path, out_dir: str | Path, seed: int | None = None) -> Path:
    """Simulate the scenario file and write `<out_dir>/<name>.csv.gz` plus `<name>.json`;
    returns the CSV path (`imufmu simulate SCENARIO.toml --out DIR [--seed N]`)."""
    data = simulate(load_scenario(scenario_path), seed)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return write_imu_csv(data, out_dir / f"{data.name}.csv.gz")
