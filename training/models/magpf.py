"""Online hard- and soft-iron estimation by particle filter (docs/magpf.md).

Two implementations of one method:

* `MagPf` — plain numpy, step by step the same as sources/ImuMagPf.c, drawing from the same
  PCG32 stream (`training.models.rng.Pcg32`), for tests and as the readable reference. Slow (the
  generator is pure Python): use it for a few hundred updates with small particle counts.
* `run_c(mag, settings)` — the C filter over a whole recording through the batch library
  (`ImuBatchMagPfRun`), which is what the FMU runs.

State x = [h_p (3) µT, b11 b12 b13 b22 b23 b33]; compensation h_c = (I + B)(h_m − h_p).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from contract import layout
from training import runtime
from training.models import magpf_rb
from training.models.rng import Pcg32

MAX_PARTICLES = 512          # IMU_MAG_PF_MAX_PARTICLES
MAX_BIN_SIDE = 4             # IMU_MAG_PF_MAX_BIN_SIDE
STATE_SIZE = 9
MAX_HIDDEN = 8
MAX_TRAINING = 64            # IMU_MAG_PF_MAX_TRAINING
RNG_STREAM = 54              # IMU_MAG_PF_RNG_STREAM
MAX_FIELD_RATIO = 20.0
MIN_FIELD_RATIO = 1e-3
RESAMPLE_FRACTION = 2.0 / 3.0
CLIP_FACTOR = 2.0            # IMU_MAG_PF_CLIP_FACTOR: change-test inputs clipped at 2 x threshold
OUTLIER_FACTOR = 4.0         # IMU_MAG_PF_OUTLIER_FACTOR: glitches kept out of the power sums
CHANGE_DIRECTIONS = 2        # IMU_MAG_PF_CHANGE_DIRECTIONS: field directions the evidence of a change covers
RETEST_DIRECTIONS = 30       # IMU_MAG_PF_RETEST_DIRECTIONS: field directions (min_rotation apart) of the prior's agreement
RETEST_MARGIN = 1.0          # IMU_MAG_PF_RETEST_MARGIN: the prior may miss by this much more per update
HILL_FRACTION = 0.9
NETWORK_INIT = 0.5
TINY = 1e-12
SOFT_INDEX = np.array([[3, 4, 5], [4, 6, 7], [5, 7, 8]])
N_OUTPUTS = 14               # compensated (3), hard iron (3), soft iron (6), N_eff, changes

#: The FMU settings the filter reads (sources/ImuPipeline.c ImuPipelinePfSettings): field_norm and
#: the pf_* parameters, with the variable table's units (pf_min_rotation in rad) and defaults.
FMU_SETTINGS = ("field_norm",) + tuple(name for name, _ in layout.SETTINGS if name.startswith("pf_"))


@dataclass(frozen=True)
class Addition:
    """One of the project's additions to mode 0 (docs/magpf.md "Mode 0"): its label and the
    settings that switch it off (the source's method) and on (as in `METHOD_WITH_ADDITIONS`)."""

    label: str
    off: dict
    on: dict


_FMU_DEFAULTS = layout.settings_defaults()
_BINS = int(_FMU_DEFAULTS["pf_sphere_bins"])
_GATE_RAD = float(_FMU_DEFAULTS["pf_min_rotation"])

#: The project's additions to the method of mode 0, in the order the ablation adds them
#: (benchmarks/magpf_ablation.py). Decimation, particle count, noise levels and thresholds are the
#: method's own parameters and stay at the defaults.
ADDITIONS = (
    Addition("roughening of the resampled cloud", {"resample_roughening": 0}, {"resample_roughening": 1}),
    Addition("Metropolis resample-move", {"enable_move": 0}, {"enable_move": 1}),
    Addition("tempering to N_eff ≥ N/2", {"enable_tempering": 0}, {"enable_tempering": 1}),
    Addition(f"direction buffer ({6 * _BINS * _BINS} bins)", {"pf_sphere_bins": 0}, {"pf_sphere_bins": _BINS}),
    Addition("innovation-driven inflation (50 updates, ≤ 20×)", {"innovation_time_constant": 0.0, "max_inflation": 1.0},
             {"innovation_time_constant": 50.0, "max_inflation": 20.0}),
    Addition("change test (threshold 100, re-draw ± 10 µT / 0, re-test of the prior)", {"change_threshold": 0.0},
             {"change_threshold": 100.0, "pf_change_spread_hard": 10.0, "change_spread_soft": 0.0}),
    Addition("glitch clipping", {"glitch_clipping": 0}, {"glitch_clipping": 1}),
)

#: Additions `METHOD_WITH_ADDITIONS` leaves off (the product's mode-0 defaults have them on); the
#: ablation adds them after it.
LATER_ADDITIONS = (
    Addition("ambient-norm mean (300 updates)", {"norm_time_constant": 0.0}, {"norm_time_constant": 300.0}),
    Addition(f"rotation gate ({math.degrees(_GATE_RAD):.1f}°)", {"pf_min_rotation": 0.0}, {"pf_min_rotation": _GATE_RAD}),
)

#: The method of mode 0 as its source describes it (issue 3, docs/magpf.md "Mode 0", steps 1–8:
#: random walk, observation ‖h_m‖² − ‖h_0‖² of the current sample, N_eff test at 2N/3,
#: double-threshold splitting, back-propagation restoration network with the entropy test,
#: systematic resampling), every addition off.
SOURCE_METHOD = {"pf_rao_blackwell": 0, **{k: v for a in ADDITIONS + LATER_ADDITIONS for k, v in a.off.items()}}

#: The method of mode 0 with the project's additions of `ADDITIONS` ("method + project additions",
#: the stabilised 9-state filter of the tables); the defaults are those of the Rao-Blackwellised mode.
METHOD_WITH_ADDITIONS = {**SOURCE_METHOD, **{k: v for a in ADDITIONS for k, v in a.on.items()}}


@functools.cache
def internal_settings() -> tuple[tuple[str, str, float], ...]:
    """(name, unit, default) of the settings that are not FMU parameters, in the order of the batch
    library's second array: read from the C filter (sources/ImuMagPf.c ImuMagPfInternal), their
    one definition. The default prior (zero around the calibrated field, spread pf_prior_spread_*)
    assumes a trained calibration as prior mean; `zero_prior` is the wide prior for an
    uncalibrated start."""
    return runtime.magpf_internal_table()


def internal_defaults() -> dict[str, float]:
    """Default of every internal setting, by name (units of `internal_settings`)."""
    return {name: value for name, _, value in internal_settings()}


def setting_names() -> tuple[str, ...]:
    """Every name `settings` knows: FMU_SETTINGS, then the internal settings."""
    return FMU_SETTINGS + tuple(internal_defaults())


def zero_prior(field_norm: float) -> dict:
    """Wide prior around zero for an uncalibrated start: 0.5 |h_0| [µT] and 0.05, adapting from the
    first sample (nothing to hold)."""
    return {"pf_prior_spread_hard": 0.5 * float(field_norm), "pf_prior_spread_soft": 0.05, "pf_hold_prior": 0}


def trained_prior(hard_iron_ut, soft_iron, spread_hard_ut: float = 0.5, spread_soft: float = 0.005) -> dict:
    """Prior settings around a known calibration (hard iron [µT], soft iron b11 b12 b13 b22 b23
    b33), as `train` would give it: tight spreads, held until a change (the default)."""
    p = {f"prior_hard_iron_{a}": float(v) for a, v in zip("xyz", hard_iron_ut)}
    p.update({f"prior_soft_iron_{k}": float(v) for k, v in zip(("xx", "xy", "xz", "yy", "yz", "zz"), soft_iron)})
    return {**p, "pf_prior_spread_hard": float(spread_hard_ut), "pf_prior_spread_soft": float(spread_soft)}


def settings(field_norm: float, **overrides) -> dict:
    """Default settings for a field norm [µT] with `overrides` (names of `setting_names`): the FMU
    defaults of contract/variables.py and the internal defaults of the C filter."""
    unknown = set(overrides) - set(setting_names())
    if unknown:
        raise ValueError(f"unknown magpf setting(s): {', '.join(sorted(unknown))}")
    fmu = layout.settings_defaults()
    s = {name: fmu[name] for name in FMU_SETTINGS}
    s["field_norm"] = float(field_norm)
    s.update(internal_defaults())
    s.update(overrides)
    return s


def settings_arrays(s: dict) -> tuple[np.ndarray, np.ndarray]:
    """The two arrays of the batch entry: the FMU settings array (contract.layout SETTINGS order,
    FMU defaults where s has no value) and the internal settings in the order of `internal_settings`."""
    fmu = np.array(layout.settings_array({name: s[name] for name in FMU_SETTINGS}), dtype=np.float64)
    internal = np.array([float(s[name]) for name, _, _ in internal_settings()], dtype=np.float64)
    return fmu, internal


# ----------------------------------------------------------------------------- C batch entry


def check_settings_c(s: dict) -> str | None:
    """None if the C filter accepts the settings, else its message naming the setting."""
    return runtime.magpf_settings_problem(*settings_arrays(s))


@dataclass(frozen=True)
class MagPfRun:
    """Per-sample outputs of a filter run: compensated (N, 3) µT, hard_iron (N, 3) µT,
    soft_iron (N, 6) [b11 b12 b13 b22 b23 b33], neff (N,) particles, changes (N,) changes of
    environment declared so far."""

    compensated: np.ndarray
    hard_iron: np.ndarray
    soft_iron: np.ndarray
    neff: np.ndarray
    changes: np.ndarray


def _split_outputs(out: np.ndarray) -> MagPfRun:
    return MagPfRun(out[:, 0:3], out[:, 3:6], out[:, 6:12], out[:, 12], out[:, 13])


def run_c(mag, s: dict) -> MagPfRun:
    """Run the C filter (ImuBatchMagPfRun) over raw field samples mag (N, 3) µT."""
    message = check_settings_c(s)
    if message is not None:
        raise ValueError(f"magpf settings rejected: {message}")
    m = np.ascontiguousarray(mag, dtype=np.float64)
    if m.ndim != 2 or m.shape[1] != 3:
        raise ValueError(f"mag must have shape (N, 3), got {m.shape}")
    fmu, internal = settings_arrays(s)
    out = np.empty((m.shape[0], N_OUTPUTS), dtype=np.float64)
    if runtime.load_runtime().ImuBatchMagPfRun(runtime.pointer(fmu), fmu.size, runtime.pointer(internal), internal.size, m.shape[0], runtime.pointer(m),
                               runtime.pointer(out)) != 0:
        raise ValueError("ImuBatchMagPfRun failed")
    return _split_outputs(out)


def rng_draw_c(seed: int, stream: int, kind: str, n: int) -> np.ndarray:
    """n draws of the C generator: kind 'u32', 'uniform' or 'normal'."""
    out = np.empty(n, dtype=np.float64)
    code = {"u32": 0, "uniform": 1, "normal": 2}[kind]
    if runtime.load_runtime().ImuBatchRngDraw(float(seed), float(stream), code, n, runtime.pointer(out)) != 0:
        raise ValueError("ImuBatchRngDraw rejected its arguments")
    return out


# ----------------------------------------------------------------------------- model functions


def soft_matrix(soft) -> np.ndarray:
    """(…, 3, 3) symmetric B from (…, 6) entries b11 b12 b13 b22 b23 b33."""
    soft = np.asarray(soft, dtype=np.float64)
    return soft[..., SOFT_INDEX - 3]


def apply(x, mag) -> np.ndarray:
    """(I + B)(mag − h_p) [µT] for states x (…, 9) and fields mag (…, 3) µT."""
    x = np.asarray(x, dtype=np.float64)
    d = np.asarray(mag, dtype=np.float64) - x[..., :3]
    return d + np.einsum("...ij,...j->...i", soft_matrix(x[..., 3:]), d)


def observation(x, mag) -> np.ndarray:
    """h(x) = |mag|² − |(I + B)(mag − h_p)|² [µT²] (the C form; equals the expanded form)."""
    m = np.asarray(mag, dtype=np.float64)
    c = apply(x, m)
    return np.sum(m * m, axis=-1) - np.sum(c * c, axis=-1)


def observation_noise_moments(sigma_ut: float, field_norm_ut: float) -> tuple[float, float]:
    """Mean 3σ² [µT²] and variance 4|h_0|²σ² + 6σ⁴ [µT⁴] of |h + v|² − |h|², v ~ (0, σ²I)."""
    var = sigma_ut * sigma_ut
    return 3.0 * var, 4.0 * field_norm_ut * field_norm_ut * var + 6.0 * var * var


def effective_sample_size(w) -> float:
    """N_eff = 1 / Σ w² of normalised weights."""
    w = np.asarray(w, dtype=np.float64)
    return float(1.0 / np.sum(w * w))


def hill_number(log_w) -> float:
    """exp(−Σ p ln p) of the weights exp(log_w) normalised (effective number of species, ≤ m)."""
    lw = np.asarray(log_w, dtype=np.float64)
    p = np.exp(lw - lw.max())
    p /= p.sum()
    nz = p[p > 0]
    return float(math.exp(-np.sum(nz * np.log(nz))))


def systematic_indices(w, u0: float) -> np.ndarray:
    """Systematic resampling: for offsets (u0 + k)/N, the index of the particle whose cumulative
    weight first reaches it (the C loop: start = U/N, target = start + k/N)."""
    w = np.asarray(w, dtype=np.float64)
    n = w.size
    start = u0 / n
    out = np.empty(n, dtype=np.int64)
    i, cumulative = 0, w[0]
    for k in range(n):
        target = start + k / n
        while target > cumulative and i < n - 1:
            i += 1
            cumulative += w[i]
        out[k] = i
    return out


def split_plan(w, high_weight: float, low_weight: float):
    """Double-threshold splitting plan: (high indices, low indices, n) with n = floor(#low/#high);
    n < 2 (or no high-weight particle) means no split."""
    w = np.asarray(w, dtype=np.float64)
    high = np.flatnonzero(w > high_weight)
    low = np.flatnonzero((w < low_weight) & ~(w > high_weight))
    n = len(low) // len(high) if len(high) else 0
    return high, low, n


# ----------------------------------------------------------------------------- test data


@dataclass(frozen=True)
class TumblingData:
    """Simulated magnetometer record: mag (N, 3) raw µT, truth (N, 3) body field µT,
    hard_iron (N, 3) µT and soft_iron (N, 6) true per sample, rate_hz, field_norm_ut."""

    mag: np.ndarray
    truth: np.ndarray
    hard_iron: np.ndarray
    soft_iron: np.ndarray
    rate_hz: float
    field_norm_ut: float


def _tumbling_attitudes(n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """(n, 3, 3) rotation matrices body -> nav of a smooth random tumble (|w| ~ 1.5 rad/s)."""
    rates = np.cumsum(rng.normal(0.0, 0.6 * math.sqrt(dt), (n, 3)), axis=0)
    rates = rates - np.linspace(0.0, 1.0, n)[:, None] * rates[-1]      # bounded drift
    rates = 1.5 * rates / max(1e-9, float(np.sqrt(np.mean(np.sum(rates ** 2, axis=1)))))
    rates += 0.8 * np.stack([np.sin(0.31 * dt * np.arange(n)), np.cos(0.23 * dt * np.arange(n)),
                             np.sin(0.17 * dt * np.arange(n) + 1.0)], axis=1)
    r = np.empty((n, 3, 3))
    current = np.eye(3)
    for k in range(n):
        r[k] = current
        w = rates[k] * dt
        angle = float(np.linalg.norm(w))
        if angle > 0:
            a = w / angle
            kx = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
            current = current @ (np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx)
    return r


def simulate_tumbling(seed: int, duration_s: float = 60.0, rate_hz: float = 100.0,
                      field_norm_ut: float = 60.0, dip_deg: float = 60.0,
                      hard_iron=(30.0, 40.0, 20.0), soft_iron=(0.03, 0.05, -0.04, -0.02, 0.03, 0.04),
                      jump_at_s: float | None = None, jump_ut=(20.0, 0.0, 0.0),
                      noise_uniform_ut: float = 0.3, noise_t_scale_ut: float = 0.1,
                      noise_t_dof: float = 3.0) -> TumblingData:
    """Tumbling IMU in a uniform field with hard/soft iron and non-Gaussian noise.

    h_m = (I + B)⁻¹ h + h_p + v with h = Rᵀ m_nav the true body field, v = U(−a, a) + s·t_ν per
    axis (a uniform + Student-t mixture; default std ≈ 0.25 µT). With `jump_at_s`, h_p jumps by
    `jump_ut` at that time. Attitudes from a smooth random rate covering the sphere.
    """
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * rate_hz))
    dip = math.radians(dip_deg)
    m_nav = field_norm_ut * np.array([math.cos(dip), 0.0, math.sin(dip)])
    truth = np.einsum("nji,j->ni", _tumbling_attitudes(n, 1.0 / rate_hz, rng), m_nav)
    hp = np.tile(np.asarray(hard_iron, dtype=np.float64), (n, 1))
    if jump_at_s is not None:
        hp[int(round(jump_at_s * rate_hz)):] += np.asarray(jump_ut, dtype=np.float64)
    soft = np.tile(np.asarray(soft_iron, dtype=np.float64), (n, 1))
    inv = np.linalg.inv(np.eye(3) + soft_matrix(soft[0]))
    noise = (rng.uniform(-noise_uniform_ut, noise_uniform_ut, (n, 3))
             + noise_t_scale_ut * rng.standard_t(noise_t_dof, (n, 3)))
    mag = truth @ inv.T + hp + noise
    return TumblingData(mag, truth, hp, soft, rate_hz, field_norm_ut)


# ----------------------------------------------------------------------------- numpy twin


class MagPf:
    """The filter of sources/ImuMagPf.c in numpy, drawing from the same PCG32 stream.

    Same operations in the same order as the C code, so runs agree with `run_c` to rounding
    (numpy's exp/log/tanh and summation order may differ from C by an ulp; see
    tests/test_magpf.py for the tolerance). `s` is a settings dict (`settings()`).
    """

    def __init__(self, s: dict) -> None:
        message = check_settings_c(s)
        if message is not None:
            raise ValueError(f"magpf settings rejected: {message}")
        self.s = dict(s)
        self.n = int(s["pf_particles"])
        var = float(s["pf_measurement_noise"]) ** 2
        self.field_sq = float(s["field_norm"]) ** 2
        self.obs_mean = 3.0 * var
        self.half_inv_var = 0.5 / (4.0 * self.field_sq * var + 6.0 * var * var)
        self.high_weight = float(s["pf_threshold_high"]) / self.n
        self.low_weight = float(s["pf_threshold_low"]) / self.n
        self.rough = float(s["roughening"]) * float(self.n) ** (-1.0 / STATE_SIZE)
        self.q = np.array([s["pf_process_noise_hard"]] * 3 + [s["pf_process_noise_soft"]] * 6, float)
        tc = float(s["innovation_time_constant"])
        self.innovation_rate = 1.0 / tc if tc > 0 else 0.0
        self.min_rotation_cos = math.cos(float(s["pf_min_rotation"]))
        self.reset()

    def reset(self) -> None:
        """Reseed and draw the prior (weights 1/N)."""
        s = self.s
        self.rng = Pcg32(int(s["pf_seed"]), RNG_STREAM)
        self.neff = float(self.n)
        self.innovation_average = 1.0
        self.prior_average = 1.0
        self.inflation = 1.0
        self.counter = 0
        self.last_used = np.zeros(3)
        k = int(s["pf_sphere_bins"])
        self.bins = np.zeros((max(1, 6 * k * k), 3))
        self.bin_list: list[int] = []
        self.updates_since_change = 0
        self.change_armed = False
        self.changes = 0
        self.frozen = False
        self.residual_mean = 0.0
        self.retesting = False
        self._clear_evidence()
        if int(s["pf_rao_blackwell"]):
            magpf_rb.reset(self)
            return
        self._draw_prior()

    def _prior_state(self) -> np.ndarray:
        """ImuMagPfPriorState: the prior calibration [h_p µT, b11 b12 b13 b22 b23 b33]."""
        s = self.s
        return np.array([s[f"prior_hard_iron_{a}"] for a in "xyz"]
                        + [s[f"prior_soft_iron_{k}"] for k in ("xx", "xy", "xz", "yy", "yz", "zz")], dtype=np.float64)

    def _draw_prior(self) -> None:
        """ImuMagPfDrawPrior (mode 0): the cloud around the prior calibration, weights 1/N."""
        s = self.s
        spread = np.array([s["pf_prior_spread_hard"]] * 3 + [s["pf_prior_spread_soft"]] * 6, float)
        self.particle = self._prior_state() + spread * self.rng.normals(self.n * STATE_SIZE).reshape(self.n, STATE_SIZE)
        self.weight = np.full(self.n, 1.0 / self.n)
        self.estimate = self.weight @ self.particle

    def _prior_explains(self, mag: np.ndarray) -> bool:
        """ImuMagPfPriorExplains: after a declared change, True once the prior calibration explains
        the data from RETEST_DIRECTIONS directions as well as the estimate (RETEST_MARGIN)."""
        threshold = float(self.s["change_threshold"])
        if not self.retesting or threshold <= 0.0 or self.innovation_rate <= 0.0:
            return False
        z = self._clip(self._innovation(mag, self._prior_state()))
        if self.prior_average > threshold:
            self.retest_updates = 0
            self.retest_directions = 0
            self.retest_prior_sum = 0.0
            self.retest_estimate_sum = 0.0
            return False
        self.retest_updates += 1
        self.retest_prior_sum += z
        self.retest_estimate_sum += self._clip(self._innovation(mag))
        if self.retest_directions == 0 or self._turned(self.retest_direction, mag):
            self.retest_directions += 1
            self.retest_direction = mag.copy()
        return (self.retest_directions >= RETEST_DIRECTIONS
                and self.retest_prior_sum <= self.retest_estimate_sum + RETEST_MARGIN * self.retest_updates)

    def _change_centre(self) -> np.ndarray:
        """ImuMagPfChangeCentre: the prior calibration if its average is under the change threshold
        (the change returned to it), else the estimate."""
        if self.prior_average <= float(self.s["change_threshold"]):
            return self._prior_state()
        return self.estimate.copy()

    def _take_back_prior(self) -> None:
        """ImuMagPfRbTakeBackPrior / ImuMagPfSplitTakeBackPrior: the mode re-draws its particles around the
        prior calibration, then the common part (ImuMagPfPriorTakenBack)."""
        average = self.prior_average
        if int(self.s["pf_rao_blackwell"]):
            magpf_rb.reset(self)
        else:
            self._draw_prior()
            self.bin_list = []
            self.change_armed = False
        self.innovation_average = average
        self.inflation = 1.0
        self.updates_since_change = 0
        self.retesting = False
        self._clear_evidence()

    # -- steps ------------------------------------------------------------------------------

    def _valid(self, mag: np.ndarray) -> bool:
        if not np.all(np.isfinite(mag)):
            return False
        norm = float(np.sqrt(mag @ mag))
        f = float(self.s["field_norm"])
        return MIN_FIELD_RATIO * f < norm < MAX_FIELD_RATIO * f

    def _turned(self, reference: np.ndarray, mag: np.ndarray) -> bool:
        """ImuMagPfTurned: the direction of mag is more than min_rotation from reference's."""
        norm = float(np.sqrt(mag @ mag))
        last = float(np.sqrt(reference @ reference))
        return (float(self.s["pf_min_rotation"]) <= 0.0 or last <= 0.0
                or float(mag @ reference) < self.min_rotation_cos * norm * last)

    def _rotated(self, mag: np.ndarray) -> bool:
        return self._turned(self.last_used, mag)

    def _residual(self, mag: np.ndarray, x: np.ndarray | None = None) -> float:
        """|h_m|² − |h_0|² − h(x) − noise mean [µT²] of a state (default the estimate; ImuMagPfResidual)."""
        x = self.estimate if x is None else x
        norm_sq = float(mag[0] * mag[0] + mag[1] * mag[1] + mag[2] * mag[2])
        return norm_sq - self.field_sq - float(observation(x, mag)) - self.obs_mean

    def _innovation(self, mag: np.ndarray, x: np.ndarray | None = None) -> float:
        """Normalised innovation squared of a sample against a state (default the estimate), the
        averaged residual removed (ImuMagPfInnovationOf)."""
        e = self._residual(mag, x) - self.residual_mean
        return 2.0 * self.half_inv_var * e * e

    def _clip(self, z: float) -> float:
        clip = CLIP_FACTOR * float(self.s["change_threshold"]) if int(self.s["glitch_clipping"]) else 0.0
        return clip if clip > 0.0 and z > clip else z

    def _clear_evidence(self) -> None:
        """ImuMagPfClearEvidence."""
        self.evidence_directions = 0
        self.evidence_direction = np.zeros(3)
        self.retest_updates = 0
        self.retest_directions = 0
        self.retest_direction = np.zeros(3)
        self.retest_prior_sum = 0.0
        self.retest_estimate_sum = 0.0

    def _outlier(self, mag: np.ndarray) -> bool:
        threshold = float(self.s["change_threshold"])
        return (bool(int(self.s["glitch_clipping"])) and threshold > 0.0 and self.change_armed
                and self._innovation(mag) > OUTLIER_FACTOR * threshold)

    def _adapt(self, mag: np.ndarray) -> None:
        if self.innovation_rate <= 0.0:
            return
        # the prior calibration's average: the hypothesis of every re-test
        self.prior_average += self.innovation_rate * (self._clip(self._innovation(mag, self._prior_state()))
                                                      - self.prior_average)
        z = self._innovation(mag)
        clipped = self._clip(z)
        if float(self.s["norm_time_constant"]) > 0.0 and clipped == z:   # a glitch is no ambient norm
            self.residual_mean += (self._residual(mag) - self.residual_mean) / float(self.s["norm_time_constant"])
        z = clipped
        self.innovation_average += self.innovation_rate * (z - self.innovation_average)
        self.inflation = min(max(math.sqrt(self.innovation_average), 1.0),
                             float(self.s["max_inflation"]))

    def _bin_index(self, mag: np.ndarray) -> int:
        """Cube-map bin (6 faces × k × k) of the direction of mag − ĥ_p."""
        k = int(self.s["pf_sphere_bins"])
        d = mag - self.estimate[:3]
        ad = np.abs(d)
        a = (0 if ad[0] >= ad[2] else 2) if ad[0] >= ad[1] else (1 if ad[1] >= ad[2] else 2)
        scale = 0.5 * k / ad[a] if d[a] != 0.0 else 0.0
        u = min(max(math.floor(d[(a + 1) % 3] * scale + 0.5 * k), 0), k - 1)
        v = min(max(math.floor(d[(a + 2) % 3] * scale + 0.5 * k), 0), k - 1)
        return ((2 * a + int(d[a] < 0.0)) * k + u) * k + v

    def _store(self, mag: np.ndarray) -> None:
        b = self._bin_index(mag) if int(self.s["pf_sphere_bins"]) > 0 else 0
        if b not in self.bin_list:
            self.bin_list.append(b)
        self.bins[b] = mag

    def log_likelihood(self, x: np.ndarray) -> np.ndarray:
        """log p(buffer | x) = −Σ_b (y_b − h(x, mag_b) − 3σ²)² / (2 var) for states x (M, 9),
        in the equal form y_b − h(x, mag_b) = |(I + B)(mag_b − h_p)|² − |h_0|²."""
        x = np.atleast_2d(x)
        total = np.zeros(x.shape[0])
        for b in self.bin_list:
            c = apply(x, self.bins[b])
            e = (c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1] + c[:, 2] * c[:, 2]) - (self.field_sq + self.obs_mean)
            total = total + e * e
        return -total * self.half_inv_var

    def _weigh(self) -> float:
        self.loglik = self.log_likelihood(self.particle)
        loglik = self.loglik
        mean = float(np.sum(self.weight * loglik))
        var = float(np.sum(self.weight * (loglik - mean) ** 2))
        alpha = math.sqrt(math.log(2.0) / var) if int(self.s["enable_tempering"]) and var > math.log(2.0) else 1.0
        with np.errstate(divide="ignore"):
            lw = np.where(self.weight > 0, np.log(np.where(self.weight > 0, self.weight, 1.0)),
                          -np.inf) + alpha * loglik
        w = np.exp(lw - lw.max())
        self.weight = w / w.sum()
        return alpha

    def _declare_change(self) -> None:
        self.innovation_average = 1.0
        self.inflation = 1.0
        self.updates_since_change = 0
        self.change_armed = False
        self.changes += 1
        self.residual_mean = 0.0
        self.retesting = True
        self._clear_evidence()

    def _change_declared(self, mag: np.ndarray) -> bool:
        """ImuMagPfChangeDeclared: the evidence must persist over CHANGE_DIRECTIONS field directions."""
        s = self.s
        self.updates_since_change += 1
        threshold = float(s["change_threshold"])
        if threshold <= 0.0:
            return False
        if not self.change_armed:
            self.change_armed = (self.updates_since_change >= float(s["innovation_time_constant"])
                                 and self.innovation_average < threshold)
            return False
        if self.innovation_average <= threshold:
            self.evidence_directions = 0
            return False
        if self._innovation(mag) > threshold and (
                self.evidence_directions == 0 or self._turned(self.evidence_direction, mag)):
            self.evidence_directions += 1
            self.evidence_direction = mag.copy()
        if self.evidence_directions < (CHANGE_DIRECTIONS if self.frozen else 1):
            return False
        self._declare_change()
        return True

    def _redraw(self) -> None:
        """ImuMagPfRedraw: after a declared change, the cloud around the estimate, the buffer flushed."""
        s = self.s
        spread = np.array([s["pf_change_spread_hard"]] * 3 + [s["change_spread_soft"]] * 6, float)
        self.particle = self._change_centre() + spread * self.rng.normals(
            self.n * STATE_SIZE).reshape(self.n, STATE_SIZE)
        self.weight = np.full(self.n, 1.0 / self.n)
        self.bin_list = []

    def _cloud_sigma(self) -> np.ndarray:
        return self.rough * self.particle.std(axis=0)

    def update(self, mag) -> bool:
        """Feed one raw sample (3,) µT; True if the filter updated."""
        mag = np.asarray(mag, dtype=np.float64)
        if not self._valid(mag):
            return False
        if int(self.s["pf_rao_blackwell"]):
            return magpf_rb.update(self, mag)
        if not self._rotated(mag):
            return False
        self.counter += 1
        if self.counter < int(self.s["pf_decimation"]):
            return False
        self.counter = 0
        self.last_used = mag.copy()
        # an isolated glitch (innovation average still low) would stay in its direction bin until that recurs
        glitch = self._outlier(mag) and self.innovation_average <= float(self.s["change_threshold"])
        self._adapt(mag)
        if self._change_declared(mag):
            self._redraw()
            glitch = False
        elif self._prior_explains(mag):   # the change was a glitch, or it returned
            self._take_back_prior()
            return False
        if not glitch:
            self._store(mag)
        self.particle = self.particle + self.inflation * self.q * self.rng.normals(
            self.n * STATE_SIZE).reshape(self.n, STATE_SIZE)
        alpha = self._weigh()
        threshold = RESAMPLE_FRACTION * self.n
        self.neff = effective_sample_size(self.weight)
        if self.neff < threshold and int(self.s["enable_splitting"]):
            self._split(alpha)
            self.weight = self.weight / self.weight.sum()
            self.neff = effective_sample_size(self.weight)
        if self.neff < threshold:
            self._resample(alpha)
        self.estimate = self.weight @ self.particle
        return True

    def compensate(self, mag) -> np.ndarray:
        """(I + B)(mag − h_p) [µT] with the current estimate."""
        return apply(self.estimate, mag)

    def _resample(self, alpha: float) -> None:
        sigma = self._cloud_sigma()
        idx = systematic_indices(self.weight, self.rng.uniform())
        self.particle = self.particle[idx]
        parent_loglik = self.loglik[idx]
        self.weight = np.full(self.n, 1.0 / self.n)
        if not int(self.s["resample_roughening"]):
            return
        move = int(self.s["enable_move"])
        for k in range(self.n):
            proposal = self.particle[k] + sigma * self.rng.normals(STATE_SIZE)
            if move:
                ll = float(self.log_likelihood(proposal[None, :])[0])
                u = self.rng.uniform()
                if not (ll >= parent_loglik[k] or u < math.exp(alpha * (ll - parent_loglik[k]))):
                    continue
            self.particle[k] = proposal

    # -- splitting and the restoration network -------------------------------------------------

    def _split(self, alpha: float) -> None:
        high, low, n = split_plan(self.weight, self.high_weight, self.low_weight)
        if len(high) == 0 or n < 2:
            return
        sigma = self._cloud_sigma()
        self._train(high)
        m = len(high) * (n - 1)
        slots = low[:m]
        parents = np.repeat(high, n - 1)
        for _ in range(int(self.s["max_tries"])):
            self.particle[slots] = self.particle[parents] + sigma * self.rng.normals(
                m * STATE_SIZE).reshape(m, STATE_SIZE)
            log_r = alpha * (self._predict(self.particle[slots]) - self._predict(self.particle[parents]))
            if hill_number(log_r) > HILL_FRACTION * m:
                break
            sigma = sigma * 0.5
        share = self.weight[high] / n
        fam = log_r.reshape(len(high), n - 1)
        r = np.exp(fam - fam.max(axis=1, keepdims=True))
        self.weight[slots] = ((n - 1) * share[:, None] * r / r.sum(axis=1, keepdims=True)).ravel()
        self.weight[high] = share

    def _train(self, high: np.ndarray) -> None:
        """Set up and train the network on the first ≤ MAX_TRAINING high-weight particles."""
        idx = high[:MAX_TRAINING]
        x, t = self.particle[idx], self.loglik[idx]
        units = int(self.s["hidden_units"])

        def moments(v):
            mean = float(np.sum(v) / len(v))
            sd = math.sqrt(float(np.sum((v - mean) ** 2)) / len(v))
            return mean, (1.0 / sd if sd > TINY * (abs(mean) + 1.0) else 1.0)

        self.out_mean, self.out_gain = moments(t)
        mg = [moments(x[:, j]) for j in range(STATE_SIZE)]
        self.in_mean = np.array([a for a, _ in mg])
        self.in_gain = np.array([b for _, b in mg])
        w1, b1, w2 = np.empty((units, STATE_SIZE)), np.empty(units), np.empty(units)
        for u in range(units):
            w1[u] = [NETWORK_INIT * (2.0 * self.rng.uniform() - 1.0) for _ in range(STATE_SIZE)]
            b1[u] = NETWORK_INIT * (2.0 * self.rng.uniform() - 1.0)
            w2[u] = NETWORK_INIT * (2.0 * self.rng.uniform() - 1.0)
        b2 = 0.0
        xn = (x - self.in_mean) * self.in_gain
        tn = (t - self.out_mean) * self.out_gain
        step = float(self.s["learning_rate"]) / len(idx)
        for _ in range(int(self.s["training_epochs"])):
            hidden = np.tanh(b1 + xn @ w1.T)
            err = b2 + hidden @ w2 - tn
            delta = err[:, None] * w2 * (1.0 - hidden * hidden)
            g_w2, g_b1, g_w1 = err @ hidden, delta.sum(axis=0), delta.T @ xn
            w2 = w2 - step * g_w2
            b1 = b1 - step * g_b1
            w1 = w1 - step * g_w1
            b2 = b2 - step * float(err.sum())
        self.net = (w1, b1, w2, b2)

    def _predict(self, x: np.ndarray) -> np.ndarray:
        """Network prediction of the log likelihood l(x) [1] for states x (M, 9)."""
        w1, b1, w2, b2 = self.net
        hidden = np.tanh(b1 + ((x - self.in_mean) * self.in_gain) @ w1.T)
        return (b2 + hidden @ w2) / self.out_gain + self.out_mean


def run_python(mag, s: dict) -> MagPfRun:
    """Run the numpy twin over mag (N, 3) µT (slow: tests and small N only)."""
    pf = MagPf(s)
    m = np.asarray(mag, dtype=np.float64)
    out = np.empty((m.shape[0], N_OUTPUTS))
    for k in range(m.shape[0]):
        pf.update(m[k])
        out[k, :3] = pf.compensate(m[k])
        out[k, 3:12] = pf.estimate
        out[k, 12] = pf.neff
        out[k, 13] = pf.changes
    return _split_outputs(out)
