"""Rest detection on the raw signals (training.selfcal.poses groups the rests into poses).

A sample belongs to a rest when a sliding window of WINDOW_S around it is still on every recorded
triad: the windowed standard deviation of each axis is below a threshold set from the recording's
own noise floor (a low quantile of the windowed std, times a factor), bounded below by
LSB_FACTOR quantisation steps and above by a physical cap. Variance, not magnitude, decides: a gyro
with a bias of several °/s is still detected at rest, and an uncalibrated accelerometer too. Every
recorded triad votes, so a slow turn about the vertical (gravity constant, gyro nearly constant)
is caught by the magnetometer when it is fast enough to lift the field's windowed std, and a static
thermal log without accelerometer still works.

The noise floor holds when rests are rare: a robot or vehicle log still only for a second at each
end has far fewer than NOISE_QUANTILE of its windows still, and the quantile then measures motion.
The floor then comes from the *quiet* windows alone (quiet on every axis of every triad at once),
which are the still ones whenever a rest exists.

A steady slow turn has a constant rate and a smoothly moving gravity direction: no std test sees
it. Each still run is therefore cut where the mean specific force drifts beyond its noise (chunk
means compared over the run), and a piece whose gravity direction turns faster than
REST_TILT_DPS (and significantly, against the noise of the fitted tilt rate) is not a rest.
The magnetometer does not take part: a still sensor's field drifts in a disturbance
(xio_handheld, still at 97.6-100.2 s: field heading 0.72 °/s, gyro 0.00 °/s).

Rests are split where the temperature moves by more than REST_TEMP_SPLIT_C (a warm-up changes
the bias within a long rest) and at gaps in the time stamps.

A pose held in the hand is not a rest: tremor (4-12 Hz) lifts the gyro std 10-30x above the
noise floor. Such a *hold* still gives a good mean specific force (the hand's position is steady)
and field direction, so holds are detected too, with physical tolerances on tremor-filtered
signals: the tilt steady to HOLD_TILT_DEG and the rate (bias from the rests removed) below
HOLD_RATE_DPS. Holds serve the pose invariants (gravity norm, dip, rest-to-rest rotation), never
the gyro bias; they need at least one rest (for the bias) and a recorded accelerometer.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from training.data.dataset import TRIADS, ImuData
from training.data.reference import true_runs

#: Length of the sliding window [s]: long enough that its std estimates the noise to ~15 %
#: (25 samples at 100 Hz, 12 at 50 Hz), short against a held pose of a few seconds.
WINDOW_S = 0.25
#: Fewest samples in a window, whatever the rate: below 5 the std is meaningless.
MIN_WINDOW_SAMPLES = 5
#: Quantile of the windowed std that estimates the noise floor: a calibration log is still for
#: far more than 5 % of its windows, so this quantile is the std of a still window (a low one:
#: the windowed std of white noise has a spread of ~15-20 %, so the 5 % point is ~0.65-0.75 σ).
NOISE_QUANTILE = 0.05
#: ... but a log still for less than that (a robot arm moving 60 s between 1 s rests: 4 % of its
#: windows) puts the quantile in motion (scenarios/variants/robot_log.toml: gyro 0.0052 rad/s, 10x
#: the still windows' ~0.0005, and 0 on an axis that repeats its count). When it exceeds
#: RARE_REST_RATIO x the same quantile over the quiet windows only — each axis of every triad at
#: most its median std, which are the still windows whenever the log has a rest — it measured
#: motion, and the quiet windows' quantile is the floor. Where the log is mostly still the two
#: agree to 1.31x or better (measured: imucal_ferraris <= 1.10, xio_handheld <= 1.17, BROAD's 20
#: trials <= 1.12, pan_thermal 1.18, the protocol, calibration, eval_handheld and two_soaks twins
#: <= 1.31); in a log that is all rest the quiet windows are the jointly quietest and their 5 %
#: point is the 2.5 % point of all, 1.06x lower at 25 samples a window, 1.35x at 5. 2 leaves every
#: such floor as it was and still catches motion.
RARE_REST_RATIO = 2.0
#: Threshold at least LSB_FACTOR quantisation steps: a still sensor whose noise is below one step
#: repeats a count (windowed std 0, so the floor can be 0) or toggles between two (std at most
#: 0.51 step in a 25-sample window) or, now and then, across two steps (0-2 alternating: 1.02
#: step); 1.5 steps passes all of them, and hides at most a rate change of 0.3 °/s within a
#: window for a 0.061 °/s LSB (16 bit at ±2000 °/s).
LSB_FACTOR = 1.5
#: Threshold = NOISE_FACTOR x the noise-floor quantile: 3 x 0.65 σ ≈ 2 σ, above the 99.9 % point
#: of the windowed std of a still sensor (≈ 1.5-1.7 σ for 12-25 samples), so rests are not cut up
#: by noise; motion that stays under it moves the window mean by less than ~2 σ of noise.
NOISE_FACTOR = 3.0
#: Physical upper caps of the threshold per triad (triad unit), for a log with too little rest
#: for the quantile to see the noise: 0.035 rad/s = 2 °/s (VQF's default rest threshold; a rate
#: fluctuating by more than that turns the sensor by ~1° within a window), 0.2 m/s² (~20 mg,
#: a tilt change of ~1°), 3 µT (~3.5° of a 50 µT field). Every MEMS grade has noise below them.
STD_CAP = {"gyr": 0.035, "acc": 0.2, "mag": 3.0}
#: Shortest rest [s]: a pose held on purpose lasts longer; the turning points of natural motion
#: are still for < 0.2 s. 0.5 s holds >= 25 samples at 50 Hz, so the rest mean has 1/5 of the noise.
MIN_REST_S = 0.5
#: Fastest turn of the gravity direction that a rest may hide [°/s]: on the measured logs the rests
#: of 2 s or more turn by at most 0.062 °/s (BROAD trial 08; imucal_ferraris 0.014, xio_handheld
#: 0.060), shorter ones by up to 0.26 °/s within 1.5 standard errors (noise); a steady slow turn
#: that no std test sees is 1 °/s or more (a robot's creep, a hand turning a pose slowly). A rest
#: turning at 0.2 °/s would move its gyro mean by up to that much: the price of not cutting real
#: rests.
REST_TILT_DPS = 0.2
#: Drift tests are at DRIFT_SIGMAS standard errors: chunk means of the specific force (each of
#: one window) farther apart than DRIFT_SIGMAS x √2 x their noise (σ ≈ threshold / 2 per sample:
#: NOISE_FACTOR x a floor of 0.65-0.75 σ), plus REST_TILT_DPS x their time apart, end a still
#: stretch; and a stretch's fitted tilt rate must stay below DRIFT_SIGMAS x its standard error
#: (or REST_TILT_DPS). No rest of the measured logs or the twins above is cut or refused by them
#: (their largest fitted tilt rate above REST_TILT_DPS is 2.9 standard errors: eval_handheld twin).
DRIFT_SIGMAS = 4.0
#: A rest whose gyro mean leaves the line through its neighbours' by more than this [°/s] turns
#: about the vertical (which the accelerometer cannot see): the still rests of the measured logs
#: stay within 0.058 °/s of it (xio_handheld; BROAD, imucal_ferraris <= 0.039), and a consumer
#: gyro's g-sensitivity (~0.1 °/s/g) moves the bias by up to 0.2 °/s between opposite poses;
#: 0.5 °/s leaves 2.5x that and still catches a 1 °/s turn.
REST_RATE_JUMP_DPS = 0.5
#: ... judged only when the middle rest's temperature is within this [°C] of the line through its
#: neighbours' (or unknown): a bias drifting by up to 0.06 °/s/°C (pan_thermal) then moves by
#: 0.06 °/s at most, and a thermal cycle (cold, hot, cold) is not mistaken for a turn.
REST_RATE_TEMP_C = 1.0
#: A time step above GAP_FACTOR x the median step is a gap (dropped samples, a logger paused
#: between thermal soaks): windows never span it and rests end at it.
GAP_FACTOR = 3.0
#: A rest is split where its temperature has moved this much [°C] (and the piece lasts
#: MIN_REST_S): a bias drift of ~0.01-0.1 °/s per °C then changes by at most a few thousandths
#: of a °/s within one window, so the window mean is the bias at the window's mean temperature.
REST_TEMP_SPLIT_C = 0.5
#: Moving average that removes hand tremor before the hold test [s]: its first zero is at 4 Hz,
#: the low end of physiological tremor (4-12 Hz).
TREMOR_S = 0.25
#: Window of the hold test on the tremor-filtered signals [s].
HOLD_WINDOW_S = 0.5
#: A hold keeps the tremor-filtered specific force steady to this tilt [deg]: its std per axis
#: must stay below g sin(HOLD_TILT_DEG) ≈ 0.086 m/s², so the hold's mean direction is good to a
#: fraction of a degree (a pose placed on a table is steadier still).
HOLD_TILT_DEG = 0.5
#: A hold turns at most this fast [°/s] (tremor-filtered rate minus the bias at rest): a hand
#: holding a pose drifts by ~1-2 °/s; slower than this, heading drift within a few-second hold
#: stays below ~5°, and heading does not enter the gravity-norm or dip invariants.
HOLD_RATE_DPS = 3.0
#: Shortest hold [s]: a pose held on purpose (the protocol asks for a few seconds).
MIN_HOLD_S = 1.0
#: Standard gravity [m/s²], for the hold tilt tolerance only (a ±0.3 % local variation is
#: irrelevant there).
_G = 9.80665


@dataclass(frozen=True)
class RestWindow:
    """One rest: samples [start, stop) of recording `dataset`, times [s], sample count, and the
    means over it of gyr (3,) rad/s, acc (3,) m/s², mag (3,) µT (NaN when not recorded), temp °C,
    with the per-axis std (3,) of each triad; `pose` indexes the gravity direction (-1 when
    the accelerometer is not recorded); kind = 'rest' (still to the noise floor) or 'hold'
    (a pose held by hand: tilt steady, slow drift allowed); edge = 'start' or 'end' when the
    window begins within one std window of the recording's first sample or ends within one of
    its last, 'whole' when both, '' for a window inside the recording."""

    dataset: int
    start: int
    stop: int
    t_start: float
    t_stop: float
    count: int
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    temp: float
    gyr_std: np.ndarray
    acc_std: np.ndarray
    mag_std: np.ndarray
    pose: int = -1
    kind: str = "rest"
    edge: str = ""

    def as_dict(self) -> dict:
        """JSON-ready summary (lists, floats; NaN -> None)."""
        def clean(v):
            return [None if not np.isfinite(x) else float(x) for x in np.atleast_1d(v)]
        return {"dataset": self.dataset, "start": self.start, "stop": self.stop,
                "t_start": self.t_start, "t_stop": self.t_stop, "count": self.count,
                "gyr": clean(self.gyr), "acc": clean(self.acc), "mag": clean(self.mag),
                "temp": clean(self.temp)[0], "pose": self.pose, "kind": self.kind, "edge": self.edge}


@dataclass(frozen=True)
class RestDetection:
    """Rests of one recording: windows (rests and holds, in time order), the (N,) mask of the
    rests (not the holds), and per recorded triad the noise floor (3,) and threshold (3,) of the
    windowed std [triad unit]; window length [samples]; why no holds were searched ('' if they were);
    per triad (3,) bool: the floor came from the quiet windows because the NOISE_QUANTILE of all
    windows measured motion (rests are rare); the still stretches refused because gravity turned
    in them, as (t_start, t_stop, tilt rate °/s); the recording's first and last time [s]."""

    windows: tuple[RestWindow, ...]
    mask: np.ndarray
    noise_floor: dict
    threshold: dict
    window_samples: int
    hold_note: str = ""
    rare_rest_floor: dict = field(default_factory=dict)
    turning: tuple = ()
    span_s: tuple = (float("nan"), float("nan"))

    @property
    def rests(self) -> list[RestWindow]:
        """The rests (not the holds), in time order."""
        return [w for w in self.windows if w.kind == "rest"]

    @property
    def ends_only(self) -> bool:
        """True when the recording has rests and every one of them is at its start or end (a robot
        or vehicle log): the gyro bias is then pinned there only, and nothing in between."""
        rests = self.rests
        return bool(rests) and all(w.edge for w in rests)

    @property
    def longest_motion_s(self) -> float:
        """Longest time [s] without a rest or hold: between two windows, or from the recording's
        start to the first / from the last to its end (the whole span when there is none)."""
        edges = [self.span_s[0]] + [x for w in self.windows for x in (w.t_start, w.t_stop)] + [self.span_s[1]]
        return float(max(b - a for a, b in zip(edges[::2], edges[1::2])))


def _window_sums(x: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(finite count, sum, sum of squares) over every w-sample window of x (n, 3), NaN skipped;
    x is centred on its mean first so that the running sums stay well conditioned."""
    finite = np.isfinite(x)
    x = np.where(finite, x - (np.nanmean(x, axis=0) if finite.any() else 0.0), 0.0)
    def window(v):
        c = np.concatenate([np.zeros((1, 3)), np.cumsum(v, axis=0)])
        return c[w:] - c[:-w]
    return window(finite.astype(float)), window(x), window(x * x)


def windowed_std(x: np.ndarray, w: int) -> np.ndarray:
    """Std (n - w + 1, 3) of every w-sample window of x (n, 3), window i = rows i..i+w-1 (ddof 1);
    NaN samples are skipped, and a window with fewer than half its samples finite is NaN."""
    n, s1, s2 = _window_sums(x, w)
    with np.errstate(invalid="ignore", divide="ignore"):
        std = np.sqrt(np.maximum(s2 - s1 * s1 / n, 0.0) / (n - 1))
    return np.where(n >= max(2, w / 2), std, np.nan)


def quantisation_step(x: np.ndarray) -> np.ndarray:
    """Smallest step (3,) between distinct finite values per axis [unit] (0 for a constant axis):
    a still sensor whose noise is below one step still toggles by it."""
    out = np.zeros(3)
    for i in range(3):
        v = np.unique(x[np.isfinite(x[:, i]), i])
        if v.size > 1:
            out[i] = float(np.min(np.diff(v)))
    return out


def contiguous_blocks(t: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the stretches of t (N,) s without a gap (step > GAP_FACTOR x median step)."""
    if t.size < 2:
        return [(0, int(t.size))]
    dt = np.diff(t)
    cuts = np.flatnonzero(dt > GAP_FACTOR * np.median(dt)) + 1
    edges = np.concatenate([[0], cuts, [t.size]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def recorded_triads(data: ImuData) -> list[str]:
    """The triads of `data` with at least one finite sample, in TRIADS order."""
    return [k for k in TRIADS if data.has(k)]


def _window_stds(data: ImuData, triads: list[str], blocks, w: int) -> dict:
    """Per triad the windowed std (M, 3) of all windows inside the blocks, and the window starts (M,)."""
    starts = np.concatenate([np.arange(a, b - w + 1) for a, b in blocks if b - a >= w] or [[]])
    out = {"starts": starts.astype(int)}
    for k in triads:
        x = getattr(data, k)
        out[k] = np.concatenate([windowed_std(x[a:b], w) for a, b in blocks if b - a >= w]
                                or [np.zeros((0, 3))])
    return out


def quiet_windows(stds: dict, triads: list[str]) -> np.ndarray:
    """(M,) bool: windows whose std is at most the axis's median over the recording on every axis
    of every triad in `triads` (stds: triad -> (M, 3)); a NaN std is not quiet. Still windows are
    quiet on all axes at once; motion lifts at least one."""
    quiet = np.ones(stds["starts"].size, dtype=bool)
    for k in triads:
        with np.errstate(invalid="ignore"):
            quiet &= np.all(stds[k] <= np.nanmedian(stds[k], axis=0), axis=1)
    return quiet


def noise_thresholds(stds: np.ndarray, raw: np.ndarray, triad: str, quiet: np.ndarray | None = None,
                     min_quiet: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(noise floor (3,), threshold (3,), rare-rest flag (3,) bool) of one triad from its windowed
    stds (M, 3) and raw samples (N, 3): floor = NOISE_QUANTILE quantile of the finite stds; where
    that exceeds RARE_REST_RATIO x the same quantile over the `quiet` windows (M,) bool (at least
    `min_quiet` of them), it measured motion and the quiet windows' quantile is the floor (flag);
    threshold = NOISE_FACTOR x floor, at least LSB_FACTOR quantisation steps, at most STD_CAP[triad]
    (the cap itself on an axis that never changes value)."""
    def quantile(s):
        s = s[np.isfinite(s)]
        return float(np.quantile(s, NOISE_QUANTILE)) if s.size else np.nan
    floor = np.array([quantile(s) for s in stds.T])
    rare = np.zeros(3, dtype=bool)
    if quiet is not None and quiet.sum() >= min_quiet:
        still = np.array([quantile(s) for s in stds[quiet].T])
        rare = RARE_REST_RATIO * still < floor
        floor = np.where(rare, still, floor)
    step = quantisation_step(raw)
    threshold = np.minimum(np.maximum(NOISE_FACTOR * floor, LSB_FACTOR * step), STD_CAP[triad])
    # an axis that reads one value throughout (a still quantised sensor repeating its count) has
    # std 0 everywhere and a floor and step of 0: it cannot tell rest from motion, so it never vetoes
    return floor, np.where(step > 0, threshold, STD_CAP[triad]), rare


def _still_mask(n: int, starts: np.ndarray, still: np.ndarray, w: int) -> np.ndarray:
    """(n,) bool: samples covered by at least one still window (window i covers i..i+w-1)."""
    cover = np.zeros(n + 1, dtype=int)
    np.add.at(cover, starts[still], 1)
    np.add.at(cover, starts[still] + w, -1)
    return np.cumsum(cover)[:n] > 0


def _runs(mask: np.ndarray, blocks) -> list[tuple[int, int]]:
    """[start, stop) of the True runs of mask (N,), cut at block boundaries."""
    return [(a + s, a + e) for a, b in blocks for s, e in true_runs(mask[a:b])]


def _split_by_temperature(a: int, b: int, t: np.ndarray, temp: np.ndarray) -> list[tuple[int, int]]:
    """Pieces [start, stop) of the rest a..b, cut where the temperature has moved
    REST_TEMP_SPLIT_C since the piece began and the piece lasts MIN_REST_S; a short tail joins
    the last piece."""
    pieces, start = [], a
    for k in range(a + 1, b):
        if (np.isfinite(temp[k]) and np.isfinite(temp[start])
                and abs(temp[k] - temp[start]) > REST_TEMP_SPLIT_C and t[k] - t[start] >= MIN_REST_S):
            pieces.append((start, k))
            start = k
    if pieces and t[b - 1] - t[start] < MIN_REST_S:
        pieces[-1] = (pieces[-1][0], b)
    else:
        pieces.append((start, b))
    return pieces


def _window(data: ImuData, index: int, a: int, b: int) -> RestWindow:
    """The RestWindow of samples a..b-1 of recording `index`."""
    def stats(x):
        seg = x[a:b]
        if not np.isfinite(seg).any():
            return np.full(3, np.nan), np.full(3, np.nan)
        return np.nanmean(seg, axis=0), np.nanstd(seg, axis=0)
    (g, gs), (f, fs), (h, hs) = stats(data.gyr), stats(data.acc), stats(data.mag)
    temp = data.temp[a:b]
    mean_temp = float(np.nanmean(temp)) if np.isfinite(temp).any() else float("nan")
    return RestWindow(index, a, b, float(data.t[a]), float(data.t[b - 1]), b - a, g, f, h,
                      mean_temp, gs, fs, hs)


def moving_average(x: np.ndarray, m: int) -> np.ndarray:
    """Mean (n - m + 1, 3) of every m-sample window of x (n, 3), window i = rows i..i+m-1; NaN
    samples are skipped, and a window with fewer than half its samples finite is NaN."""
    n, s1, _ = _window_sums(x, m)
    centre = np.nanmean(x, axis=0) if np.isfinite(x).any() else np.zeros(3)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n >= max(1, m / 2), s1 / n + centre, np.nan)


def _hold_windows(data: ImuData, blocks, step: float, bias: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(window starts (M,), hold ok (M,), covered samples per window) of the hold test on the
    tremor-filtered acc and gyro (gyro minus `bias` (N, 3) rad/s)."""
    m = max(2, int(round(TREMOR_S / step)))
    w = max(MIN_WINDOW_SAMPLES, int(round(HOLD_WINDOW_S / step)))
    acc_limit = _G * np.sin(np.deg2rad(HOLD_TILT_DEG))
    rate_limit = np.deg2rad(HOLD_RATE_DPS)
    starts, ok = [], []
    for a, b in blocks:
        if b - a < m + w:
            continue
        lp_acc = moving_average(data.acc[a:b], m)
        rate = np.linalg.norm(moving_average(data.gyr[a:b] - bias[a:b], m), axis=1)
        steady = np.all(windowed_std(lp_acc, w) < acc_limit, axis=1)
        slow = np.lib.stride_tricks.sliding_window_view(rate, w).max(axis=1) < rate_limit
        starts.append(np.arange(a, b - m - w + 2))
        ok.append(steady & slow)
    if not starts:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=bool), m + w - 1
    return np.concatenate(starts), np.concatenate(ok), m + w - 1


def rest_bias(t: np.ndarray, rests: list[RestWindow]) -> np.ndarray:
    """Gyro bias (N, 3) rad/s at times t (N,) s: the rest means interpolated linearly in time
    between the rests' mid-times (held beyond the first and last), so a bias drifting with
    temperature during a warm-up is followed."""
    centres = np.array([0.5 * (w.t_start + w.t_stop) for w in rests])
    means = np.array([w.gyr for w in rests])
    return np.column_stack([np.interp(t, centres, means[:, i]) for i in range(3)])


def _chunk_edges(a: int, b: int, w: int) -> np.ndarray:
    """Sample indices (J + 1,) cutting a..b into J = (b - a) // w chunks of w to 2w - 1 samples."""
    j = max(1, (b - a) // w)
    return a + (np.arange(j + 1) * (b - a)) // j


def _steady_stretches(mean: np.ndarray, t: np.ndarray, tol: np.ndarray,
                      slope: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) chunk ranges, in order, within which every two chunk means (J, 3) at times
    t (J,) [s] differ per axis by at most tol (3,) + slope (3,) x their time apart; a chunk that
    breaks that starts the next range. Pairs i < j need μ_j - s t_j <= tol + min_i (μ_i - s t_i)
    and max_i (μ_i + s t_i) <= tol + μ_j + s t_j, so a running min and max suffice."""
    out, start = [], 0
    low, high = mean[0] - slope * t[0], mean[0] + slope * t[0]
    for j in range(1, len(mean)):
        down, up = mean[j] - slope * t[j], mean[j] + slope * t[j]
        if np.all(down <= tol + low) and np.all(high <= tol + up):
            low, high = np.minimum(low, down), np.maximum(high, up)
        else:
            out.append((start, j))
            start, low, high = j, down, up
    out.append((start, len(mean)))
    return out


def tilt_rate(t: np.ndarray, acc: np.ndarray) -> tuple[float, float]:
    """(rate, standard error) [rad/s] at which the specific force acc (n, 3) m/s² at times t (n,) s
    turns: the straight-line fit's slope across the mean direction over the mean norm, and the norm
    of the slopes' standard errors (from the residuals, white noise assumed) over the same norm."""
    ok = np.all(np.isfinite(acc), axis=1)
    t, acc = t[ok], acc[ok]
    if t.size < 3:
        return 0.0, np.inf
    tc = t - t.mean()
    sxx = float(tc @ tc)
    mean = acc.mean(axis=0)
    beta = tc @ (acc - mean) / sxx
    res = acc - mean - np.outer(tc, beta)
    se = np.sqrt(np.sum(res * res, axis=0) / (t.size - 2) / sxx)
    g = float(np.linalg.norm(mean))
    if not g > 0:
        return 0.0, np.inf
    u = mean / g
    return float(np.linalg.norm(beta - (beta @ u) * u)) / g, float(np.linalg.norm(se)) / g


def _steady_pieces(data: ImuData, a: int, b: int, w: int, acc_threshold: np.ndarray | None):
    """(pieces, turning) of the still run a..b: pieces [start, stop) within which the specific
    force neither drifts (chunk means of w samples: `_steady_stretches`, noise σ = acc_threshold / 2
    per sample) nor turns (`tilt_rate` below REST_TILT_DPS or below DRIFT_SIGMAS standard errors);
    turning: (t_start, t_stop, rate °/s) of the stretches that did turn, or of the whole run when
    a turn faster than REST_TILT_DPS cut it into stretches too short for a rest. The whole run
    when the accelerometer is not recorded (acc_threshold None)."""
    if acc_threshold is None:
        return [(a, b)], []
    edges = _chunk_edges(a, b, w)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # an all-NaN chunk: NaN mean, never steady
        mean = np.array([np.nanmean(data.acc[s:e], axis=0) for s, e in zip(edges[:-1], edges[1:])])
        g = float(np.linalg.norm(np.nanmean(data.acc[a:b], axis=0)))
    t = np.array([data.t[s:e].mean() for s, e in zip(edges[:-1], edges[1:])])
    tol = DRIFT_SIGMAS * np.sqrt(2.0) * 0.5 * acc_threshold / np.sqrt(w)
    slope = np.full(3, g * np.deg2rad(REST_TILT_DPS) if np.isfinite(g) else 0.0)
    pieces, turning = [], []
    for i, j in _steady_stretches(mean, t, tol, slope):
        s, e = int(edges[i]), int(edges[j])
        if data.t[e - 1] - data.t[s] < MIN_REST_S:
            continue
        rate, se = tilt_rate(data.t[s:e], data.acc[s:e])
        if rate > max(np.deg2rad(REST_TILT_DPS), DRIFT_SIGMAS * se):
            turning.append((float(data.t[s]), float(data.t[e - 1]), float(np.rad2deg(rate))))
        else:
            pieces.append((s, e))
    if not pieces and not turning and data.t[b - 1] - data.t[a] >= MIN_REST_S:
        rate = tilt_rate(data.t[a:b], data.acc[a:b])[0]
        if rate > np.deg2rad(REST_TILT_DPS):   # a steady turn cut into stretches shorter than a rest
            turning.append((float(data.t[a]), float(data.t[b - 1]), float(np.rad2deg(rate))))
    return pieces, turning


def _rest_windows(data: ImuData, index: int, mask: np.ndarray, blocks, w: int,
                  acc_threshold: np.ndarray | None) -> tuple[list[RestWindow], list]:
    """(RestWindows, turning stretches) of the runs of `mask`: each run cut into steady pieces
    (`_steady_pieces`), those lasting MIN_REST_S cut by temperature; `mask` keeps those pieces
    only (cleared elsewhere in place)."""
    windows, turning = [], []
    for a, b in _runs(mask, blocks):
        mask[a:b] = False
        pieces, turned = _steady_pieces(data, a, b, w, acc_threshold)
        turning += turned
        for s, e in pieces:
            if data.t[e - 1] - data.t[s] < MIN_REST_S:
                continue
            mask[s:e] = True
            windows += [_window(data, index, p, q) for p, q in _split_by_temperature(s, e, data.t, data.temp)]
    return windows, turning


def _rate_outliers(rests: list[RestWindow]) -> dict[int, float]:
    """Index into `rests` (time order) -> turn rate [°/s] of the rests that turn about the vertical:
    the accelerometer cannot see that, but the gyro mean then differs from the bias by the turn
    rate. A rest whose mean rate leaves the line (in time) through its two neighbours' by more than
    max(REST_RATE_JUMP_DPS, DRIFT_SIGMAS standard errors of the three means), while those two agree
    to that much and its temperature is within REST_RATE_TEMP_C of their line, is one; found
    greedily, the largest first, each removed before the next is judged (two turning rests around
    a still one then do not condemn it). The first and last rest have a neighbour on one side only
    and are never judged."""
    idx = [i for i, w in enumerate(rests) if np.all(np.isfinite(w.gyr))]
    centre = {i: 0.5 * (rests[i].t_start + rests[i].t_stop) for i in idx}
    se2 = {i: float(np.sum(rests[i].gyr_std ** 2)) / rests[i].count for i in idx}
    out = {}
    while len(idx) >= 3:
        worst, worst_excess, worst_rate = None, 1.0, 0.0
        for a, m, b in zip(idx[:-2], idx[1:-1], idx[2:]):
            tol = max(np.deg2rad(REST_RATE_JUMP_DPS), DRIFT_SIGMAS * np.sqrt(se2[a] + se2[m] + se2[b]))
            frac = (centre[m] - centre[a]) / (centre[b] - centre[a])
            temp_off = rests[m].temp - (rests[a].temp + frac * (rests[b].temp - rests[a].temp))
            if np.linalg.norm(rests[b].gyr - rests[a].gyr) > tol or abs(temp_off) > REST_RATE_TEMP_C:
                continue   # (a NaN temperature compares False: judged)
            rate = float(np.linalg.norm(rests[m].gyr - rests[a].gyr - frac * (rests[b].gyr - rests[a].gyr)))
            if rate / tol > worst_excess:
                worst, worst_excess, worst_rate = m, rate / tol, rate
        if worst is None:
            break
        out[worst] = float(np.rad2deg(worst_rate))
        idx.remove(worst)
    return out


def _mark_edges(windows: list[RestWindow], n: int, w: int) -> list[RestWindow]:
    """The windows with `edge` set: 'start' when one begins within w samples of the recording's
    first sample, 'end' when it stops within w of its last (n samples), 'whole' when both."""
    def edge(win):
        first, last = win.start < w, win.stop > n - w
        return "whole" if first and last else "start" if first else "end" if last else ""
    return [replace(win, edge=edge(win)) for win in windows]


def _hold_list(data: ImuData, index: int, rest_mask: np.ndarray, blocks, step: float,
               rests: list[RestWindow]) -> tuple[list[RestWindow], str]:
    """(hold windows, '' or why no hold was searched) outside the rests of one recording."""
    if not data.has("acc"):
        return [], "no holds: the accelerometer is not recorded"
    gyro_rests = [w for w in rests if np.all(np.isfinite(w.gyr))]
    if not gyro_rests:
        return [], "no holds: no rest gives the gyro bias that the hold's rate test needs"
    starts, ok, span = _hold_windows(data, blocks, step, rest_bias(data.t, gyro_rests))
    hold = _still_mask(len(data), starts, ok, span) & ~rest_mask
    out = []
    for a, b in _runs(hold, blocks):
        if data.t[b - 1] - data.t[a] >= MIN_HOLD_S:
            out.append(replace(_window(data, index, a, b), kind="hold"))
    return out, ""


def detect_rest(data: ImuData, index: int = 0) -> RestDetection:
    """Rests and holds of one recording `data` (index = its position in the caller's list).

    Raises ValueError when no triad is recorded."""
    triads = recorded_triads(data)
    if not triads:
        raise ValueError(f"{data.name}: no triad recorded, rest detection impossible")
    n = len(data)
    blocks = contiguous_blocks(data.t)
    step = float(np.median(np.diff(data.t))) if n > 1 else 1.0
    w = max(MIN_WINDOW_SAMPLES, int(round(WINDOW_S / step)))
    stds = _window_stds(data, triads, blocks, w)
    quiet = quiet_windows(stds, triads)
    # one rest of MIN_REST_S holds this many windows: fewer quiet ones cannot be a rest's
    min_quiet = max(1, int(round(MIN_REST_S / step)) - w + 1)
    floors, thresholds, rare, still = {}, {}, {}, np.ones(stds["starts"].size, dtype=bool)
    for k in triads:
        floors[k], thresholds[k], rare[k] = noise_thresholds(stds[k], getattr(data, k), k, quiet, min_quiet)
        # a NaN std (missing samples in the window) fails the comparison: not still
        still &= np.all(stds[k] < thresholds[k], axis=1)
    mask = _still_mask(n, stds["starts"], still, w)
    rests, turning = _rest_windows(data, index, mask, blocks, w, thresholds.get("acc"))
    turned = _rate_outliers(rests)
    for i, rate in turned.items():
        mask[rests[i].start:rests[i].stop] = False
        turning.append((rests[i].t_start, rests[i].t_stop, rate))
    rests = [win for i, win in enumerate(rests) if i not in turned]
    turning.sort()
    holds, note = _hold_list(data, index, mask, blocks, step, rests) if "gyr" in triads else (
        [], "no holds: the gyroscope is not recorded")
    windows = _mark_edges(sorted(rests + holds, key=lambda win: win.start), n, w)
    return RestDetection(tuple(windows), mask, floors, thresholds, w, note, rare, tuple(turning),
                         (float(data.t[0]), float(data.t[-1])))
