"""Rao-Blackwellised mode of the particle filter, numpy twin of sources/ImuMagPfRb.c.

The particles carry the hard iron only (particle[:, :3] µT); particle[:, 3:] holds the posterior
mean of m = [M11 M12 M13 M22 M23 M33] given that hard iron, where I + M = (I + B)ᵀ(I + B). Each
filter update bridges the weighted cloud from the previous target to the current one (adaptive
tempering with resample-move); see docs/magpf.md. Functions take the `training.models.magpf.MagPf`
instance, like the C functions take the filter struct, and follow the C code operation by operation.
"""
from __future__ import annotations

import math

import numpy as np

from training.models import magmoments as mm

BRIDGE_STEPS = 8
BISECTIONS = 40
MIN_BRIDGE_STEP = 1e-6
MOVE_SWEEPS = 2
IDLE_SWEEPS = 1
MOVE_SCALE = 2.38 * 2.38 / 3.0
MOVE_FLOOR = 1e-10
MAX_SOFT = 0.3
MIN_SOFT_SPREAD = 1e-4


def _reference(pf) -> np.ndarray:
    return np.array([pf.s[f"prior_hard_iron_{a}"] for a in "xyz"], dtype=np.float64)


def set_prior(pf, centre, spread: float, soft_mean, soft_spread: float) -> None:
    pf.prior = mm.MarginalPrior(
        hard_centre=np.asarray(centre, dtype=np.float64) - _reference(pf), hard_spread=float(spread),
        soft_mean=np.asarray(soft_mean, dtype=np.float64).copy(),
        soft_spread=soft_spread if soft_spread > MIN_SOFT_SPREAD else MIN_SOFT_SPREAD,
        offset=pf.field_sq + pf.obs_mean, variance=0.5 / pf.half_inv_var,
        min_eigen=(1.0 - MAX_SOFT) * (1.0 - MAX_SOFT), max_eigen=(1.0 + MAX_SOFT) * (1.0 + MAX_SOFT))


def evaluate(pf, sums, hard) -> tuple[float, np.ndarray]:
    """(log target, posterior mean of m) of a hard iron [µT] under the power sums."""
    value, soft, _ = mm.marginal(sums, np.asarray(hard, dtype=np.float64) - _reference(pf), pf.prior)
    return value, soft


def draw(pf, centre, spread: float) -> None:
    for i in range(pf.n):
        for j in range(3):
            pf.particle[i, j] = centre[j] + spread * pf.rng.normal()
        pf.previous_log[i], pf.particle[i, 3:] = evaluate(pf, pf.previous_moments, pf.particle[i, :3])
        pf.weight[i] = 1.0 / pf.n


def estimate(pf) -> None:
    m = np.zeros(6)
    hard = np.zeros(3)
    for i in range(pf.n):
        for j in range(3):
            hard[j] += pf.weight[i] * pf.particle[i, j]
        for j in range(6):
            m[j] += pf.weight[i] * pf.particle[i, 3 + j]
    pf.estimate = np.concatenate([hard, mm.soft_from_quadratic(m)])


def reset(pf) -> None:
    s = pf.s
    pf.particle = np.zeros((pf.n, 9))
    pf.weight = np.zeros(pf.n)
    pf.previous_log = np.zeros(pf.n)
    pf.loglik = np.zeros(pf.n)
    pf.moments = [0.0] * mm.MOMENT_COUNT
    pf.previous_moments = [0.0] * mm.MOMENT_COUNT
    soft = [s[f"prior_soft_iron_{k}"] for k in ("xx", "xy", "xz", "yy", "yz", "zz")]
    set_prior(pf, _reference(pf), float(s["pf_prior_spread_hard"]), mm.quadratic_from_soft(soft),
              2.0 * float(s["pf_prior_spread_soft"]))
    draw(pf, _reference(pf), float(s["pf_prior_spread_hard"]))
    estimate(pf)
    pf.frozen = bool(int(s["pf_hold_prior"]))
    pf.change_armed = pf.frozen   # the held calibration is the baseline: a prior the data contradict is a change
    if pf.frozen:   # the held calibration is the prior itself, not the mean of its draw
        pf.estimate = np.concatenate([_reference(pf), np.asarray(soft, dtype=np.float64)])


def restart(pf, mag: np.ndarray, state: np.ndarray) -> None:
    """New segment: sums restart at mag, priors around state (the estimate or the prior calibration)."""
    s = pf.s
    centre = np.asarray(state[:3], dtype=np.float64).copy()
    soft_mean = mm.quadratic_from_soft(state[3:])
    pf.moments = [0.0] * mm.MOMENT_COUNT
    pf.previous_moments = [0.0] * mm.MOMENT_COUNT
    mm.moments_add(pf.moments, mag - _reference(pf))
    set_prior(pf, centre, float(s["pf_change_spread_hard"]), soft_mean, 2.0 * float(s["change_spread_soft"]))
    draw(pf, centre, float(s["pf_change_spread_hard"]))


def weigh_new(pf) -> bool:
    usable = False
    for i in range(pf.n):
        pf.loglik[i], pf.particle[i, 3:] = evaluate(pf, pf.moments, pf.particle[i, :3])
        usable |= pf.weight[i] > 0.0 and pf.loglik[i] > -math.inf and pf.previous_log[i] > -math.inf
    return usable


def log_weight(pf, i: int, step: float) -> float:
    now, before = pf.loglik[i], pf.previous_log[i]
    if not (pf.weight[i] > 0.0 and now > -math.inf and before > -math.inf):
        return -math.inf
    return math.log(pf.weight[i]) + step * (now - before)


def ess_after(pf, step: float) -> float:
    logs = [log_weight(pf, i, step) for i in range(pf.n)]
    largest = max(logs)
    total = squares = 0.0
    for value in logs:
        w = math.exp(value - largest)
        total += w
        squares += w * w
    return total * total / squares


def next_exponent(pf, g: float, step: int) -> float:
    half = 0.5 * pf.n
    if step >= BRIDGE_STEPS or ess_after(pf, 1.0 - g) >= half:
        return 1.0
    low, high = g, 1.0
    for _ in range(BISECTIONS):
        middle = 0.5 * (low + high)
        if ess_after(pf, middle - g) >= half:
            low = middle
        else:
            high = middle
    return low if low > g + MIN_BRIDGE_STEP else g + MIN_BRIDGE_STEP


def proposal_factor(pf) -> list[list[float]]:
    mean = [0.0, 0.0, 0.0]
    cov = [[0.0] * 3 for _ in range(3)]
    for i in range(pf.n):
        for j in range(3):
            mean[j] += pf.weight[i] * pf.particle[i, j]
    for i in range(pf.n):
        for j in range(3):
            for k in range(3):
                cov[j][k] += pf.weight[i] * (pf.particle[i, j] - mean[j]) * (pf.particle[i, k] - mean[k])
    f = [[0.0] * 3 for _ in range(3)]
    for j in range(3):
        d = MOVE_SCALE * cov[j][j] + MOVE_FLOOR
        for k in range(j):
            d -= f[j][k] * f[j][k]
        f[j][j] = math.sqrt(d) if d > 0.0 else math.sqrt(MOVE_FLOOR)
        for i in range(j + 1, 3):
            v = MOVE_SCALE * cov[i][j]
            for k in range(j):
                v -= f[i][k] * f[j][k]
            f[i][j] = v / f[j][j]
    return f


def resample(pf) -> None:
    n = pf.n
    start = pf.rng.uniform() / n
    i, cumulative = 0, pf.weight[0]
    idx = np.empty(n, dtype=np.int64)
    for k in range(n):
        target = start + k / n
        while target > cumulative and i < n - 1:
            i += 1
            cumulative += pf.weight[i]
        idx[k] = i
    pf.particle = pf.particle[idx].copy()
    pf.loglik = pf.loglik[idx].copy()
    pf.previous_log = pf.previous_log[idx].copy()
    pf.weight = np.full(n, 1.0 / n)


def move(pf, g: float, f, sweeps: int) -> None:
    for _ in range(sweeps):
        for k in range(pf.n):
            z = [pf.rng.normal(), pf.rng.normal(), pf.rng.normal()]
            proposal = np.array([pf.particle[k, j] + f[j][0] * z[0] + f[j][1] * z[1] + f[j][2] * z[2]
                                 for j in range(3)])
            now, soft = evaluate(pf, pf.moments, proposal)
            before = evaluate(pf, pf.previous_moments, proposal)[0] if g < 1.0 else now   # π_1 = π_new
            u = pf.rng.uniform()
            if not (before > -math.inf and now > -math.inf):
                continue
            accept = (before + g * (now - before)) - (
                pf.previous_log[k] + g * (pf.loglik[k] - pf.previous_log[k]))
            if accept >= 0.0 or u < math.exp(accept):
                pf.particle[k, :3] = proposal
                pf.particle[k, 3:] = soft
                pf.previous_log[k] = before
                pf.loglik[k] = now


def _normalise_log(pf, logs) -> None:
    largest = max(logs)
    w = np.array([math.exp(v - largest) for v in logs])
    total = 0.0
    for v in w:
        total += v
    pf.weight = w / total


def bridge(pf) -> None:
    threshold = (2.0 / 3.0) * pf.n
    g, step, moved = 0.0, 1, False
    while g < 1.0:
        nxt = next_exponent(pf, g, step)
        _normalise_log(pf, [log_weight(pf, i, nxt - g) for i in range(pf.n)])
        g = nxt
        total = 0.0
        for w in pf.weight:
            total += w * w
        pf.neff = 1.0 / total
        if pf.neff < threshold:
            f = proposal_factor(pf)
            resample(pf)
            if int(pf.s["enable_move"]):
                move(pf, g, f, MOVE_SWEEPS)
                moved = True
        step += 1
    if int(pf.s["enable_move"]) and not moved:   # a cloud whose weights stayed even still explores π_new
        move(pf, 1.0, proposal_factor(pf), IDLE_SWEEPS)


def informative(pf) -> bool:
    """ImuMagPfRbInformative: new samples in the sums since the last move, and either update_growth ×
    the count then (moments[0] counts the samples) or an innovation average above update_innovation."""
    added = pf.moments[0] - pf.previous_moments[0]
    return added > 0.0 and (added >= float(pf.s["update_growth"]) * pf.previous_moments[0]
                            or pf.innovation_average > float(pf.s["update_innovation"]))


def update(pf, mag: np.ndarray) -> bool:
    """One valid sample [µT] (ImuMagPfRbUpdate); True if the particles were updated."""
    if not pf.frozen and pf._rotated(mag) and not pf._outlier(mag):
        pf.last_used = mag.copy()
        mm.moments_add(pf.moments, mag - _reference(pf))
    pf.counter += 1
    if pf.counter < int(pf.s["pf_decimation"]):
        return False
    pf.counter = 0
    pf._adapt(mag)
    if pf._change_declared(mag):
        pf.frozen = False
        restart(pf, mag, pf._change_centre())
    elif pf.frozen:
        return False
    elif pf._prior_explains(mag):
        pf._take_back_prior()
        return False
    if not informative(pf):   # the change test above ran; the cloud waits for information
        return False
    if not weigh_new(pf):
        pf._declare_change()
        restart(pf, mag, pf.estimate)
        if not weigh_new(pf):   # the estimate itself is hopeless: around the prior calibration
            restart(pf, mag, pf._prior_state())
            if not weigh_new(pf):
                return False
    bridge(pf)
    pf.previous_moments = list(pf.moments)
    pf.previous_log = pf.loglik.copy()
    estimate(pf)
    return True
