"""Rest detection on the raw signals and grouping of the rests into poses.

A sample belongs to a rest when a sliding window of WINDOW_S around it is still on every recorded
triad: the windowed standard deviation of each axis is below a threshold set from the recording's
own noise floor (a low quantile of the windowed std, times a factor), bounded below by the
quantisation step and above by a physical cap. Variance, not magnitude, decides: a gyro with a
bias of several °/s is still detected at rest, and an uncalibrated accelerometer too. Every
recorded triad votes, so a slow turn about the vertical (gravity constant, gyro nearly constant)
is caught by the magnetometer, and a static thermal log without accelerometer still works.

Rests are split where the temperature moves by more than REST_TEMP_SPLIT_C (a warm-up changes
the bias within a long rest) and at gaps in the time stamps; poses group the rests by the
direction of gravity (the specific force) in the sensor frame.

A pose held in the hand is not a rest: tremor (4-12 Hz) lifts the gyro std 10-30x above the
noise floor. Such a *hold* still gives a good mean specific force (the hand's position is steady)
and field direction, so holds are detected too, with physical tolerances on tremor-filtered
signals: the tilt steady to HOLD_TILT_DEG and the rate (bias from the rests removed) below
HOLD_RATE_DPS. Holds serve the pose invariants (gravity norm, dip, rest-to-rest rotation), never
the gyro bias; they need at least one rest (for the bias) and a recorded accelerometer.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

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
#: A time step above GAP_FACTOR x the median step is a gap (dropped samples, a logger paused
#: between thermal soaks): windows never span it and rests end at it.
GAP_FACTOR = 3.0
#: A rest is split where its temperature has moved this much [°C] (and the piece lasts
#: MIN_REST_S): a bias drift of ~0.01-0.1 °/s per °C then changes by at most a few thousandths
#: of a °/s within one window, so the window mean is the bias at the window's mean temperature.
REST_TEMP_SPLIT_C = 0.5
#: Rests whose gravity directions are closer than this [deg] are one pose: hand-placed poses of
#: a calibration protocol differ by 35° or more, while one pose re-placed by hand or seen through
#: a ~1-2 % uncalibrated accelerometer scatters by a few degrees.
POSE_SEPARATION_DEG = 12.0
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
    (a pose held by hand: tilt steady, slow drift allowed)."""

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

    def as_dict(self) -> dict:
        """JSON-ready summary (lists, floats; NaN -> None)."""
        def clean(v):
            return [None if not np.isfinite(x) else float(x) for x in np.atleast_1d(v)]
        return {"dataset": self.dataset, "start": self.start, "stop": self.stop,
                "t_start": self.t_start, "t_stop": self.t_stop, "count": self.count,
                "gyr": clean(self.gyr), "acc": clean(self.acc), "mag": clean(self.mag),
                "temp": clean(self.temp)[0], "pose": self.pose, "kind": self.kind}


@dataclass(frozen=True)
class RestDetection:
    """Rests of one recording: windows (rests and holds, in time order), the (N,) mask of the
    rests (not the holds), and per recorded triad the noise floor (3,) and threshold (3,) of the
    windowed std [triad unit]; window length [samples]; why no holds were searched ('' if they were)."""

    windows: tuple[RestWindow, ...]
    mask: np.ndarray
    noise_floor: dict
    threshold: dict
    window_samples: int
    hold_note: str = ""


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


def noise_thresholds(stds: np.ndarray, raw: np.ndarray, triad: str) -> tuple[np.ndarray, np.ndarray]:
    """(noise floor (3,), threshold (3,)) of one triad from its windowed stds (M, 3) and raw
    samples (N, 3): floor = NOISE_QUANTILE quantile of the finite stds; threshold = NOISE_FACTOR x
    floor, at least one quantisation step, at most STD_CAP[triad]."""
    floor = np.array([np.quantile(s[np.isfinite(s)], NOISE_QUANTILE) if np.isfinite(s).any()
                      else np.nan for s in stds.T])
    threshold = np.minimum(np.maximum(NOISE_FACTOR * floor, quantisation_step(raw)), STD_CAP[triad])
    return floor, threshold


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


def _rest_windows(data: ImuData, index: int, mask: np.ndarray, blocks) -> list[RestWindow]:
    """RestWindows of the runs of `mask` lasting MIN_REST_S (cut by temperature); shorter runs
    are cleared from `mask` in place."""
    windows = []
    for a, b in _runs(mask, blocks):
        if data.t[b - 1] - data.t[a] < MIN_REST_S:
            mask[a:b] = False
            continue
        windows += [_window(data, index, s, e) for s, e in _split_by_temperature(a, b, data.t, data.temp)]
    return windows


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
    floors, thresholds, still = {}, {}, np.ones(stds["starts"].size, dtype=bool)
    for k in triads:
        floors[k], thresholds[k] = noise_thresholds(stds[k], getattr(data, k), k)
        # a NaN std (missing samples in the window) fails the comparison: not still
        still &= np.all(stds[k] < thresholds[k], axis=1)
    mask = _still_mask(n, stds["starts"], still, w)
    rests = _rest_windows(data, index, mask, blocks)
    holds, note = _hold_list(data, index, mask, blocks, step, rests) if "gyr" in triads else (
        [], "no holds: the gyroscope is not recorded")
    windows = sorted(rests + holds, key=lambda win: win.start)
    return RestDetection(tuple(windows), mask, floors, thresholds, w, note)


def direction_groups(vectors: np.ndarray) -> np.ndarray:
    """Group index (K,) of each vector (K, 3) by direction: greedy in order, a new group when a
    direction is more than POSE_SEPARATION_DEG from every group's first member; -1 for a
    non-finite or zero vector."""
    cos_limit = np.cos(np.deg2rad(POSE_SEPARATION_DEG))
    heads: list[np.ndarray] = []
    labels = np.full(len(vectors), -1, dtype=int)
    for k, v in enumerate(np.asarray(vectors, dtype=np.float64)):
        norm = np.linalg.norm(v)
        if not np.isfinite(norm) or norm == 0:
            continue
        u = v / norm
        match = next((i for i, head in enumerate(heads) if float(u @ head) >= cos_limit), None)
        if match is None:
            heads.append(u)
            match = len(heads) - 1
        labels[k] = match
    return labels


def group_poses(windows: list[RestWindow]) -> list[RestWindow]:
    """The windows with `pose` set by `direction_groups` of their mean specific force, in
    window order (pose -1 where the accelerometer is not recorded)."""
    labels = direction_groups(np.array([w.acc for w in windows]).reshape(-1, 3))
    return [replace(w, pose=int(label)) for w, label in zip(windows, labels)]


def count_poses(windows: list[RestWindow]) -> int:
    """Number of distinct poses among windows (pose >= 0)."""
    return len({w.pose for w in windows if w.pose >= 0})
