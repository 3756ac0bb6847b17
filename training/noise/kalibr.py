"""Kalibr-style imu.yaml from the noise block (the keys of Kalibr's IMU noise model and of
allan_variance_ros: accelerometer_noise_density [m/s²/√Hz], accelerometer_random_walk [m/s³/√Hz],
gyroscope_noise_density [rad/s/√Hz], gyroscope_random_walk [rad/s²/√Hz], rostopic, update_rate [Hz]).

Kalibr's "random walk" is the bias random walk, i.e. IEEE 952's K (rate random walk for the gyro):
same number, its unit written per √Hz ([u/s/√Hz] = [u/√s]). Each scalar is the worst (largest)
supported axis; every axis figure follows as a comment with its 68 % CI, and an unsupported scalar
is left out with a comment saying why.
"""
from __future__ import annotations

from pathlib import Path

#: Kalibr key stem per triad (the magnetometer has no key in Kalibr's model: comments only).
KALIBR_STEM = {"gyr": "gyroscope", "acc": "accelerometer"}
#: Kalibr key suffix per block figure.
KALIBR_FIGURE = {"noise_density": "noise_density", "random_walk": "random_walk"}
#: Default rostopic.
ROSTOPIC = "/imu0"


def _axis_comment(triad: str, axis: int, name: str, f: dict) -> str:
    """'#   gyr x noise_density = 5.2e-05 [4.9e-05, 5.5e-05] rad/s/√Hz (68 % CI)' or its why."""
    head = f"#   {triad} {'xyz'[axis]} {name}"
    if f["supported"]:
        return f"{head} = {f['value']:.4g} [{f['ci'][0]:.4g}, {f['ci'][1]:.4g}] {f['unit']} (68 % CI)"
    return f"{head}: not supported ({f['why']})"


def imu_yaml_text(block: dict, rostopic: str = ROSTOPIC) -> str:
    """The imu.yaml text of a noise block (training.noise.characterise, imufusion-noise/1)."""
    lines = ["# Kalibr IMU noise model (imufmu noise / imufmu train; imufusion-noise/1)",
             f"# source: {block['source']}",
             f"# still data: {block['still_seconds']:.1f} s, longest still stretch {block['longest_still_seconds']:.1f} s",
             "# scalar = the worst (largest) supported axis; random_walk = IEEE 952 K (bias random walk), "
             "[u/√s] = [u/s/√Hz]"]
    values = []
    for triad in ("acc", "gyr", "mag"):
        entry = block["triads"].get(triad)
        if entry is None:
            continue
        for name in ("noise_density", "bias_instability", "random_walk"):
            figures = [axes[name] for axes in entry["axes"]]
            lines += [_axis_comment(triad, i, name, f) for i, f in enumerate(figures)]
            stem = KALIBR_STEM.get(triad)
            if stem is None or name not in KALIBR_FIGURE:
                continue
            key = f"{stem}_{KALIBR_FIGURE[name]}"
            supported = [f["value"] for f in figures if f["supported"]]
            if supported:
                values.append(f"{key}: {max(supported):.6g}")
            else:
                lines.append(f"# {key} omitted: no axis supports it ({figures[0]['why']})")
    lines += values + [f"rostopic: {rostopic}", f"update_rate: {block['rate_hz']:.6g}"]
    return "\n".join(lines) + "\n"


def write_imu_yaml(block: dict, path: str | Path, rostopic: str = ROSTOPIC) -> Path:
    """Write imu_yaml_text(block) to `path` (UTF-8) and return it."""
    path = Path(path)
    path.write_text(imu_yaml_text(block, rostopic), encoding="utf-8")
    return path
