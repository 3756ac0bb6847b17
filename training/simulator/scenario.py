"""Scenario files (TOML): what to simulate — rate, seed, earth field, start state, the sensor
unit and a sequence of motion segments. See scenarios/calibration.toml for an annotated example.

Layout:
    sensor = "sensors/mems_grade.toml"   # sensor file relative to the scenario, or a [sensor] table
    [scenario]     name, rate_hz, seed, notes, gravity_mps2 (optional: local g [m/s²], default
                   standard gravity 9.80665; written to the sidecar when given)
    [earth_field]  norm_ut, dip_deg, declination_deg
    [start]        attitude_deg = [yaw, pitch, roll], temp_c, warmup_rise_c, warmup_tau_s
    [[segment]]    type = hold | positions | rotations | handheld | figure8, per-type keys,
                   temp_end_c (optional: ramp linearly to this temperature over the segment),
                   warmup_rise_c, warmup_tau_s (optional: power-on self-heating at its start)
"""
from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contract.errors import ScenarioError
from training.data.earth import GRAVITY_RANGE_MPS2, STANDARD_GRAVITY, EarthField
from training.simulator.population import nominal
from training.simulator.segments import AXIS_VECTORS, Figure8, Handheld, Hold, Positions, Rotations, Segment
from training.simulator.sensors import MagDistortion, SensorModel, TriadErrors
from training.simulator.temperature import TemperatureProfile
from training.simulator.toml_table import TomlTable

#: Triad -> (unit suffix used in TOML key names, factor from that unit to SI).
TRIAD_UNITS = {"gyr": ("dps", np.pi / 180.0), "acc": ("ms2", 1.0), "mag": ("ut", 1.0)}
#: Handheld pitch bound when not given [deg]: keeps ZYX Euler angles far from gimbal lock.
DEFAULT_MAX_PITCH_DEG = 70.0
#: Power-on warm-up time constant when not given [s] (typical of a MEMS package on a board).
DEFAULT_WARMUP_TAU_S = 60.0
#: Scenario names become file names.
NAME_PATTERN = re.compile(r"^[A-Za-z0-9_.-]+$")
#: Tolerance on the symmetry of the soft-iron matrix [1].
SYMMETRY_TOLERANCE = 1e-12
#: Sample rate range [Hz]: from one sample per 100 s (a slow thermal log) to 100 kHz.
RATE_RANGE_HZ = (0.01, 1.0e5)
#: Most samples a scenario may have (duration × rate_hz; about 5.6 h at 100 Hz): the simulator holds
#: every sample's truth and measurements in memory.
MAX_SAMPLES = 2_000_000
#: Largest scenario or sensor file read [bytes]; a scenario is a few kB.
MAX_TOML_BYTES = 2**20


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. Angles in rad, temperatures in °C, times in s."""

    path: Path
    name: str
    rate_hz: float
    seed: int
    notes: str
    earth: EarthField
    sensor: SensorModel
    start_attitude: np.ndarray          # (3,) ZYX [yaw, pitch, roll] rad
    start_temp_c: float
    warmup_rise_c: float
    warmup_tau_s: float
    segments: tuple[Segment, ...]
    gravity_mps2: float | None = None   # local g [m/s²]; None: standard gravity, not written to the sidecar

    @property
    def gravity(self) -> float:
        """The g the specific force is simulated with [m/s²]."""
        return STANDARD_GRAVITY if self.gravity_mps2 is None else self.gravity_mps2

    @property
    def duration_s(self) -> float:
        """Total simulated time [s]."""
        return float(sum(s.duration_s for s in self.segments))

    def temperature_profile(self) -> TemperatureProfile:
        """Breakpoints at the segment boundaries; a segment without temp_end_c holds."""
        times, temps, power_ons = [0.0], [self.start_temp_c], []
        for segment in self.segments:
            if segment.warmup_rise_c != 0.0:
                power_ons.append((times[-1], times[-1] + segment.duration_s,
                                  segment.warmup_rise_c, segment.warmup_tau_s))
            times.append(times[-1] + segment.duration_s)
            temps.append(temps[-1] if segment.temp_end_c is None else segment.temp_end_c)
        return TemperatureProfile(np.array(times), np.array(temps), self.warmup_rise_c,
                                  self.warmup_tau_s, tuple(power_ons))


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file; ScenarioError names the file and the key."""
    path = Path(path)
    top = TomlTable(read_toml(path), path, "top level")
    head = top.table("scenario")
    name = head.string("name")
    if not NAME_PATTERN.match(name):
        raise head.fail("name", f"use only letters, digits, '_', '-', '.', got {name!r}")
    rate_hz = head.number("rate_hz", low=RATE_RANGE_HZ[0], high=RATE_RANGE_HZ[1])
    seed = head.integer("seed")
    notes = head.string("notes", default="", allow_empty=True)
    gravity = head.optional_number("gravity_mps2")
    if gravity is not None and not GRAVITY_RANGE_MPS2[0] <= gravity <= GRAVITY_RANGE_MPS2[1]:
        raise head.fail("gravity_mps2", f"expected the local gravity in m/s² within {list(GRAVITY_RANGE_MPS2)}, "
                                        f"got {gravity!r}")
    head.close()
    earth = _earth_field(top.table("earth_field"))
    start = top.table("start")
    attitude = np.deg2rad(start.array("attitude_deg", (3,), default=[0.0, 0.0, 0.0]))
    temp_c = start.number("temp_c", low=-100.0, high=200.0)
    rise_c = start.number("warmup_rise_c", default=0.0, low=-50.0, high=50.0)
    tau_s = start.number("warmup_tau_s", default=DEFAULT_WARMUP_TAU_S, positive=True)
    start.close()
    sensor = _sensor(top, path)
    segments = tuple(_segment(t) for t in top.tables("segment"))
    top.close()
    _check_sample_count(path, sum(s.duration_s for s in segments), rate_hz)
    return Scenario(path, name, rate_hz, seed, notes, earth, sensor, attitude, temp_c, rise_c,
                    tau_s, segments, gravity)


def _check_sample_count(path: Path, duration_s: float, rate_hz: float) -> None:
    """ScenarioError unless duration [s] × rate [Hz] gives 2..MAX_SAMPLES samples."""
    count = duration_s * rate_hz
    if not 2 <= count <= MAX_SAMPLES:
        raise ScenarioError(f"{path}: the segments last {duration_s:.6g} s, at rate_hz {rate_hz:.6g} that is "
                            f"{count:.3g} samples; a scenario has 2..{MAX_SAMPLES} samples")


def read_toml(path: Path) -> dict:
    """Parse a TOML file (a regular file of at most MAX_TOML_BYTES); ScenarioError when missing,
    not a file, too large or malformed."""
    if not path.exists():
        raise ScenarioError(f"{path}: scenario file not found")
    if not path.is_file():
        raise ScenarioError(f"{path}: not a regular file")
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_TOML_BYTES + 1)
        if len(raw) > MAX_TOML_BYTES:
            raise ScenarioError(f"{path}: larger than {MAX_TOML_BYTES // 1024} KiB; not a scenario file")
        return tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise ScenarioError(f"{path}: not UTF-8 text ({e})") from None
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"{path}: not valid TOML: {e}") from None


def _earth_field(t: TomlTable) -> EarthField:
    """[earth_field]: norm_ut > 0, dip_deg in [−90, 90], declination_deg in [−180, 180]."""
    field = EarthField(t.number("norm_ut", positive=True),
                       t.number("dip_deg", low=-90.0, high=90.0),
                       t.number("declination_deg", low=-180.0, high=180.0))
    t.close()
    return field


# ----------------------------------------------------------------------------- sensor

def _sensor(top: TomlTable, scenario_path: Path) -> SensorModel:
    """`sensor` is a path relative to the scenario file or an inline table; a sensor that declares a
    population spread (training.simulator.population) is simulated as its nominal unit."""
    if isinstance(top.raw.get("sensor"), str):
        file = scenario_path.parent / top.string("sensor")
        return sensor_from_raw(read_toml(file), file)
    return sensor_from_raw(top.table("sensor").raw, scenario_path, "sensor")


def sensor_from_raw(raw: dict, path: Path, where: str = "top level") -> SensorModel:
    """The sensor unit of a parsed sensor table `raw` (from `path`, at table `where`), its spread
    tables ignored; ScenarioError names the file and the key of a bad value."""
    return _sensor_from_table(TomlTable(nominal(raw), path, where))


def _sensor_from_table(t: TomlTable) -> SensorModel:
    """Keys: name, [gyr], [acc], [mag]."""
    name = t.string("name")
    tables = {k: t.table(k) for k in TRIAD_UNITS}
    triads = {k: _triad(table, k) for k, table in tables.items()}
    distortion = _mag_distortion(tables["mag"])
    for table in (*tables.values(), t):
        table.close()
    return SensorModel(name, triads["gyr"], triads["acc"], triads["mag"], distortion)


def _triad(t: TomlTable, triad: str) -> TriadErrors:
    """Generic triad errors; key names carry the unit (dps, ms2, ut). Errors default to 0,
    lsb and range are required. temp_rate_{u}_per_c_per_min: bias per temperature rate;
    bias_drift_{u}_per_min: bias drift with time; g_sensitivity_dps_per_ms2 (3, 3): gyroscope only;
    bias_instability_{u}: flicker-like bias instability B [u] (training.simulator.sensors.flicker_bias)."""
    u, si = TRIAD_UNITS[triad]
    zero = [0.0, 0.0, 0.0]
    temp_rate = t.array(f"temp_rate_{u}_per_c_per_min", (3,), default=zero) * si * 60.0  # -> per (°C/s)
    g_sensitivity = (t.array("g_sensitivity_dps_per_ms2", (3, 3), default=np.zeros((3, 3)).tolist()) * si
                     if triad == "gyr" else np.zeros((3, 3)))
    errors = TriadErrors(
        bias=t.array(f"bias_{u}", (3,), default=zero) * si,
        bias_t1=t.array(f"bias_t1_{u}_per_c", (3,), default=zero) * si,
        bias_t2=t.array(f"bias_t2_{u}_per_c2", (3,), default=zero) * si,
        scale=t.array("scale", (3,), default=zero),
        scale_t1=t.array("scale_t1_per_c", (3,), default=zero),
        scale_t2=t.array("scale_t2_per_c2", (3,), default=zero),
        misalignment=_symmetric_off_diagonal(np.deg2rad(t.array("misalign_deg", (3,), default=zero))),
        temp_rate=temp_rate,
        noise_density=t.number(f"noise_density_{u}_per_sqrt_hz", default=0.0, low=0.0) * si,
        bias_walk=t.number(f"bias_walk_{u}_per_sqrt_s", default=0.0, low=0.0) * si,
        bias_instability=t.number(f"bias_instability_{u}", default=0.0, low=0.0) * si,
        lsb=t.number(f"lsb_{u}", positive=True) * si,
        full_scale=t.number(f"range_{u}", positive=True) * si,
        g_sensitivity=g_sensitivity,
        drift=t.array(f"bias_drift_{u}_per_min", (3,), default=zero) * si / 60.0)
    return errors


def _symmetric_off_diagonal(xy_xz_yz: np.ndarray) -> np.ndarray:
    """Symmetric (3, 3) matrix with zero diagonal from its off-diagonals [m_xy, m_xz, m_yz]."""
    m_xy, m_xz, m_yz = xy_xz_yz
    return np.array([[0.0, m_xy, m_xz], [m_xy, 0.0, m_yz], [m_xz, m_yz, 0.0]])


def _mag_distortion(t: TomlTable) -> MagDistortion:
    """hard_iron_ut (3,), soft_iron (3, 3) symmetric positive definite (default I),
    nonlinear_cubic_ut (3, 3) (default 0), nonlinear_ref_ut > 0 (default 50)."""
    soft = t.array("soft_iron", (3, 3), default=np.eye(3).tolist())
    if np.max(np.abs(soft - soft.T)) > SYMMETRY_TOLERANCE or np.min(np.linalg.eigvalsh(soft)) <= 0:
        raise t.fail("soft_iron", "must be symmetric positive definite")
    return MagDistortion(t.array("hard_iron_ut", (3,), default=[0.0, 0.0, 0.0]), soft,
                         t.array("nonlinear_cubic_ut", (3, 3), default=np.zeros((3, 3)).tolist()),
                         t.number("nonlinear_ref_ut", default=50.0, positive=True))


# ----------------------------------------------------------------------------- segments

def _segment(t: TomlTable) -> Segment:
    """One [[segment]] table, dispatched on its `type`."""
    kind = t.string("type", choices=tuple(SEGMENT_READERS))
    common = {"temp_end_c": t.optional_number("temp_end_c"),
              "warmup_rise_c": t.number("warmup_rise_c", default=0.0, low=-50.0, high=50.0),
              "warmup_tau_s": t.number("warmup_tau_s", default=DEFAULT_WARMUP_TAU_S, positive=True),
              "label": f"{t.path}: [{t.where}]"}
    segment = SEGMENT_READERS[kind](t, common)
    t.close()
    return segment


def _hold(t: TomlTable, common: dict) -> Hold:
    """type = "hold": duration_s."""
    return Hold(hold_s=t.number("duration_s", positive=True), **common)


def _positions(t: TomlTable, common: dict) -> Positions:
    """type = "positions": attitudes_deg (M, 3) [yaw, pitch, roll], hold_s, move_s."""
    return Positions(attitudes=np.deg2rad(t.array("attitudes_deg", (None, 3))),
                     hold_s=t.number("hold_s", positive=True),
                     move_s=t.number("move_s", positive=True), **common)


def _rotations(t: TomlTable, common: dict) -> Rotations:
    """type = "rotations": axes, rates_dps (signed), angle_deg, ramp_s, rest_s."""
    rates = t.array("rates_dps")
    if np.any(rates == 0):
        raise t.fail("rates_dps", "rates must be non-zero (the sign gives the direction)")
    segment = Rotations(axes=t.strings("axes", tuple(AXIS_VECTORS)), rates=np.deg2rad(rates),
                        angle=np.deg2rad(t.number("angle_deg", positive=True)),
                        ramp_s=t.number("ramp_s", positive=True),
                        rest_s=t.number("rest_s", positive=True), **common)
    if segment.angle / np.max(np.abs(segment.rates)) < segment.ramp_s:
        raise t.fail("ramp_s", "must be at most angle_deg / max |rates_dps| (the fastest turn "
                               "must reach its rate)")
    return segment


def _handheld(t: TomlTable, common: dict) -> Handheld:
    """type = "handheld": duration_s, rest_s, move_s, ramp_s, rate_rms_dps,
    accel_rms_ms2, band_hz, max_pitch_deg (default 70)."""
    segment = Handheld(
        total_s=t.number("duration_s", positive=True), rest_s=t.number("rest_s", positive=True),
        move_s=t.number("move_s", positive=True), ramp_s=t.number("ramp_s", positive=True),
        rate_rms=np.deg2rad(t.number("rate_rms_dps", positive=True)),
        accel_rms=t.number("accel_rms_ms2", low=0.0),
        band_hz=tuple(t.array("band_hz", (2,), positive=True)),
        max_pitch=np.deg2rad(t.number("max_pitch_deg", default=DEFAULT_MAX_PITCH_DEG,
                                      positive=True, high=85.0)), **common)
    if segment.band_hz[0] >= segment.band_hz[1]:
        raise t.fail("band_hz", f"expected [low, high] with low < high, got {list(segment.band_hz)}")
    if 2.0 * segment.ramp_s > segment.move_s:
        raise t.fail("ramp_s", "must be at most half of move_s")
    if segment.total_s < segment.move_s + 2.0 * segment.rest_s:
        raise t.fail("duration_s", "must hold at least rest_s + move_s + rest_s")
    return segment


def _figure8(t: TomlTable, common: dict) -> Figure8:
    """type = "figure8": length_m, width_m, period_s, laps, ramp_s."""
    segment = Figure8(length_m=t.number("length_m", positive=True),
                      width_m=t.number("width_m", positive=True),
                      period_s=t.number("period_s", positive=True),
                      laps=t.integer("laps", low=1), ramp_s=t.number("ramp_s", positive=True),
                      **common)
    if segment.ramp_s > segment.laps * segment.period_s:
        raise t.fail("ramp_s", "must be at most laps * period_s")
    return segment


SEGMENT_READERS = {"hold": _hold, "positions": _positions, "rotations": _rotations,
                   "handheld": _handheld, "figure8": _figure8}
