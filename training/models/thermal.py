"""Gain/bias temperature model of one sensor triad, and its adaptive-gradient fit.

Model (adaptive-gain fusion paper, 'gain/bias temperature compensation'; the C runtime
`sources/ImuThermal.c` computes the identical formula in the identical order):

    Tn  = (T - t0) / ts                       normalised temperature (Tn = 0 where T is NaN)
    G_i = 1 + sum_{k=1..P} g[i][k-1] * Tn^k    per-axis gain polynomial
    B_i = sum_{k=0..P} b[i][k] * Tn^k          per-axis bias polynomial [triad unit]
    x_c = A . (G (.) (x - B))                  A constant symmetric 3x3, (.) element-wise

A model that carries the temperature range it was calibrated on (t_range, layout version 4) is
never evaluated as a polynomial outside it (a fit on 13-48 °C evaluated at -30 °C is arbitrary):
beyond an edge G and B continue along their tangent at that edge for at most CONTINUATION_SPANS
calibrated spans, then hold (`continuation=True`, the FMU's thermal_continuation = 1), or hold their
edge value (`continuation=False`).

Polynomials are evaluated by Horner's scheme from k = P down to k = 0. The fit is full-batch
gradient descent with per-coefficient adaptive step sizes (Rprop, Riedmiller & Braun 1993).
Because G(t0) = 1 and A is symmetric, the representable family depends on t0: models fitted
on different temperature ranges are comparable through their outputs, not coefficient-wise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from contract.layout import MAX_DEGREE, TRIAD_BLOCK

#: Centre and half-range used when no temperature is known (identity normalisation) [°C].
DEFAULT_T0 = 25.0
DEFAULT_TS = 1.0
#: Smallest half-range of the training temperatures [°C]: keeps Tn of a near-isothermal
#: recording from blowing up (a 0.1 °C spread would otherwise give Tn ~ 100 at 10 °C away).
MIN_TS = 1.0
#: Rprop step-size bounds in normalised parameter units: the upper bound keeps the first
#: steps inside the O(1) range of A, g and b/s; the lower bound lets steps shrink far below
#: any useful tolerance so convergence stops on `tolerance`, not on the bound.
RPROP_STEP_BOUNDS = (1e-16, 0.5)
#: Upper-triangle index pairs of the symmetric A (the 6 free entries).
_A_FREE = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
OPTIMIZERS = ("rprop", "sgd")
#: How far beyond its calibrated range a model continues along its edge tangent, in calibrated spans
#: (t_max - t_min) (sources/ImuThermal.c IMU_THERMAL_CONTINUATION_SPANS; tests/test_calibrated_range.py
#: pins the two together).
CONTINUATION_SPANS = 1.0


def _readonly(a, shape: tuple[int, ...], name: str) -> np.ndarray:
    """A read-only float64 copy of `a`, checked against `shape`; ValueError otherwise."""
    arr = np.array(a, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"'{name}' has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"'{name}' has non-finite entries")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class ThermalModel:
    """Gain/bias temperature model of one triad (see the module docstring for the formula).

    enabled: False -> the triad passes through unchanged.
    t0, ts: centre and half-range of the normalisation [°C], ts > 0.
    degree: polynomial degree P, 0..MAX_DEGREE.
    A: (3, 3) constant symmetric matrix [1].  g: (3, P) gain coefficients [1], row = axis,
    column k-1 for Tn^k.  b: (3, P+1) bias coefficients [triad unit], column k for Tn^k.
    t_range: (t_min, t_max) [°C], the temperatures of the calibration data, t_min <= t_max; the
    model clamps T to it. None: no range known (an artefact from before layout version 4), no clamping.
    """

    enabled: bool
    t0: float
    ts: float
    degree: int
    A: np.ndarray
    g: np.ndarray
    b: np.ndarray
    t_range: tuple[float, float] | None = None

    def __post_init__(self):
        if not 0 <= int(self.degree) <= MAX_DEGREE or int(self.degree) != self.degree:
            raise ValueError(f"degree {self.degree} is not an integer in 0..{MAX_DEGREE}")
        if not (np.isfinite(self.t0) and np.isfinite(self.ts) and self.ts > 0):
            raise ValueError(f"t0={self.t0}, ts={self.ts}: need finite t0 and ts > 0")
        p = int(self.degree)
        object.__setattr__(self, "enabled", bool(self.enabled))
        object.__setattr__(self, "t0", float(self.t0))
        object.__setattr__(self, "ts", float(self.ts))
        object.__setattr__(self, "degree", p)
        object.__setattr__(self, "A", _readonly(self.A, (3, 3), "A"))
        object.__setattr__(self, "g", _readonly(self.g, (3, p), "g"))
        object.__setattr__(self, "b", _readonly(self.b, (3, p + 1), "b"))
        if self.t_range is not None:
            lo, hi = (float(v) for v in self.t_range)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                raise ValueError(f"t_range {self.t_range}: need finite t_min <= t_max [°C]")
            object.__setattr__(self, "t_range", (lo, hi))

    def with_range(self, temp: np.ndarray) -> "ThermalModel":
        """This model with t_range = (min, max) of the finite temperatures `temp` [°C]; None when
        none is finite or the model does not depend on the temperature (disabled, degree 0)."""
        finite = np.asarray(temp, dtype=np.float64)
        finite = finite[np.isfinite(finite)]
        uses_temperature = self.enabled and self.degree > 0 and finite.size > 0
        t_range = (float(finite.min()), float(finite.max())) if uses_temperature else None
        return ThermalModel(self.enabled, self.t0, self.ts, self.degree, self.A, self.g, self.b, t_range)

    @classmethod
    def identity(cls, enabled: bool = True) -> "ThermalModel":
        """The model that changes nothing: t0 = 25 °C, ts = 1 °C, P = 0, A = I, g = b = 0."""
        return cls(enabled, DEFAULT_T0, DEFAULT_TS, 0, np.eye(3), np.zeros((3, 0)),
                   np.zeros((3, 1)))

    def to_block(self) -> list[float]:
        """The flat TRIAD_BLOCK-long block of contract/layout.py (higher degrees zero-padded)."""
        g = np.zeros((3, MAX_DEGREE))
        g[:, :self.degree] = self.g
        b = np.zeros((3, MAX_DEGREE + 1))
        b[:, :self.degree + 1] = self.b
        head = [1.0 if self.enabled else 0.0, self.t0, self.ts, float(self.degree)]
        tail = [0.0, 0.0, 0.0] if self.t_range is None else [1.0, *self.t_range]
        return head + [float(v) for v in np.concatenate([self.A.ravel(), g.ravel(), b.ravel()])] + tail

    @classmethod
    def from_block(cls, block) -> "ThermalModel":
        """Inverse of `to_block`; ValueError on a wrong length, flag, degree or padding."""
        v = np.asarray(block, dtype=np.float64)
        if v.shape != (TRIAD_BLOCK,):
            raise ValueError(f"block has shape {v.shape}, expected ({TRIAD_BLOCK},)")
        if v[0] not in (0.0, 1.0):
            raise ValueError(f"enabled flag is {v[0]}, expected 0 or 1")
        p = v[3]
        if p not in range(MAX_DEGREE + 1):
            raise ValueError(f"degree {p} is not an integer in 0..{MAX_DEGREE}")
        p = int(p)
        g = v[13:13 + 3 * MAX_DEGREE].reshape(3, MAX_DEGREE)
        b = v[13 + 3 * MAX_DEGREE:TRIAD_BLOCK - 3].reshape(3, MAX_DEGREE + 1)
        if np.any(g[:, p:] != 0) or np.any(b[:, p + 1:] != 0):
            raise ValueError(f"coefficients above degree {p} are not zero")
        has_range, t_min, t_max = v[TRIAD_BLOCK - 3:]
        if has_range not in (0.0, 1.0):
            raise ValueError(f"range flag is {has_range}, expected 0 or 1")
        return cls(bool(v[0]), v[1], v[2], p, v[4:13].reshape(3, 3), g[:, :p], b[:, :p + 1],
                   (t_min, t_max) if has_range else None)


def normalised_temperature(temp: np.ndarray, t0: float, ts: float) -> np.ndarray:
    """Tn = (T - t0) / ts, (N,) [1]; 0 where T is NaN (the model's value at t0)."""
    tn = (np.asarray(temp, dtype=np.float64) - t0) / ts
    return np.where(np.isnan(tn), 0.0, tn)


def _horner(coefficients: np.ndarray, tn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(value, slope d/dTn) of sum_k c[k] * Tn^k by Horner's scheme from k = P down, the slope by the same
    recursion (ImuThermalPolynomial). c: (P+1,), tn: (N,) -> two (N,)."""
    value, slope = np.full_like(tn, coefficients[-1]), np.zeros_like(tn)
    for c in coefficients[-2::-1]:
        slope = slope * tn + value
        value = value * tn + c
    return value, slope


def calibrated_temperature(model: ThermalModel, temp: np.ndarray) -> np.ndarray:
    """The temperature (N,) [°C] the polynomials are evaluated at: `temp` clamped to model.t_range when
    the model has one and depends on T (degree >= 1); NaN stays NaN (ImuThermalClampTemperature)."""
    temp = np.asarray(temp, dtype=np.float64)
    if model.t_range is None or model.degree == 0:
        return temp
    return np.clip(temp, *model.t_range)


def continuation(model: ThermalModel, temp: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """Normalised distance (N,) [1] the polynomials continue beyond their range edge: (T − edge) / ts,
    at most CONTINUATION_SPANS spans; 0 inside the range and for NaN (ImuThermalContinuation)."""
    temp = np.asarray(temp, dtype=np.float64)
    beyond = np.where((edge == temp) | np.isnan(temp), 0.0, temp - edge)
    if model.t_range is None:
        return np.zeros_like(beyond)
    limit = CONTINUATION_SPANS * (model.t_range[1] - model.t_range[0])
    return np.clip(beyond, -limit, limit) / model.ts


def apply_thermal(model: ThermalModel, x: np.ndarray, temp: np.ndarray, continuation_on: bool = True) -> np.ndarray:
    """Corrected triad x_c = A . (G(Tn) (.) (x - B(Tn))), (N, 3) in the triad's unit.

    x: (N, 3) raw triad; temp: (N,) °C (NaN -> Tn = 0). Outside model.t_range G and B continue along
    their edge tangent (continuation_on, at most CONTINUATION_SPANS spans) or hold their edge value.
    Pure: returns a new array.
    Same operation order as ImuThermalApply in C: Horner per axis, then row i of A times
    y summed as A[i,0]*y0 + A[i,1]*y1 + A[i,2]*y2.
    """
    x = np.asarray(x, dtype=np.float64)
    if not model.enabled:
        return x.copy()
    edge = calibrated_temperature(model, temp)
    tn = normalised_temperature(edge, model.t0, model.ts)
    beyond = continuation(model, temp, edge) if continuation_on else np.zeros_like(tn)
    outside = beyond != 0.0
    y = np.empty_like(x)
    for i in range(3):
        gain, gain_slope = _horner(np.concatenate([[1.0], model.g[i]]), tn)
        bias, bias_slope = _horner(model.b[i], tn)
        gain = np.where(outside, gain + gain_slope * beyond, gain)
        bias = np.where(outside, bias + bias_slope * beyond, bias)
        y[:, i] = gain * (x[:, i] - bias)
    a = model.A
    return np.column_stack([a[i, 0] * y[:, 0] + a[i, 1] * y[:, 1] + a[i, 2] * y[:, 2]
                            for i in range(3)])


@dataclass(frozen=True)
class ThermalFit:
    """Result of `GainBiasFitter.fit`.

    loss_history: mean squared error per iteration of the data divided by s, the RMS of
    all raw and reference values [1].
    rms_before / rms_after: RMS of (x_raw - x_ref) and (x_c - x_ref) over all used samples
    and axes, in `unit`. rows_dropped: rows with a non-finite raw or reference value.
    """

    model: ThermalModel
    loss_history: tuple[float, ...]
    iterations: int
    converged: bool
    rms_before: float
    rms_after: float
    rows_used: int
    rows_dropped: int
    unit: str
    posterior_cov: np.ndarray | None = None  # with a fleet prior: covariance of θ (training.models.prior order)

    @property
    def posterior_sigma(self) -> np.ndarray | None:
        """σ of θ with a fleet prior (the square root of the covariance's diagonal), else None."""
        return None if self.posterior_cov is None else np.sqrt(np.clip(np.diag(self.posterior_cov), 0.0, None))


#: Width of a temperature cluster [°C] (reference fits here, rest windows in training.selfcal): a MEMS bias drifts smoothly, by ~0.01-0.1 °/s or
#: ~1 mg per °C, so samples within 2.5 °C of each other pin down one point of B(T), not a slope.
CLUSTER_WIDTH_C = 2.5
#: Share of the finite temperature samples a cluster must hold to count: a transit through a
#: temperature during a ramp of a few seconds does not pin the model there.
CLUSTER_MIN_SHARE = 0.02


def temperature_clusters(temp: np.ndarray) -> int:
    """Number of distinct temperatures [°C] the data pin down: CLUSTER_WIDTH_C-wide bins holding
    at least CLUSTER_MIN_SHARE of the finite samples (0 when none is finite). A polynomial B(T) of
    degree d needs d + 1 of them."""
    finite = np.asarray(temp, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return 0
    bins = np.floor((finite - finite.min()) / CLUSTER_WIDTH_C).astype(int)
    counts = np.bincount(bins)
    return int(np.sum(counts >= CLUSTER_MIN_SHARE * finite.size))


def temperature_normalisation(temp: np.ndarray) -> tuple[float, float] | None:
    """(t0, ts) = centre and half-range of the finite temperatures [°C], ts >= MIN_TS;
    None when no temperature is finite."""
    finite = temp[np.isfinite(temp)]
    if finite.size == 0:
        return None
    lo, hi = float(finite.min()), float(finite.max())
    return 0.5 * (lo + hi), max(0.5 * (hi - lo), MIN_TS)


def _symmetric(a6: torch.Tensor) -> torch.Tensor:
    """(3, 3) symmetric matrix from its 6 upper-triangle entries (order: _A_FREE)."""
    rows = [[None] * 3 for _ in range(3)]
    for n, (i, j) in enumerate(_A_FREE):
        rows[i][j] = rows[j][i] = a6[n]
    return torch.stack([torch.stack(r) for r in rows])


def _model_torch(a6, g, beta, u, vand):
    """Torch form of the model on normalised data: A . (G (.) (u - B)), (N, 3).

    vand: (N, P+1) columns Tn^0..Tn^P; g: (3, P) or None (P = 0); beta: (3, P+1) = b / s.
    """
    gain = 1.0 if g is None else 1.0 + vand[:, 1:] @ g.T
    y = gain * (u - vand @ beta.T)
    return y @ _symmetric(a6)  # A symmetric: y @ A == (A @ y.T).T


class GainBiasFitter:
    """Fits the gain/bias temperature model of one triad to raw/reference pairs.

    degree: polynomial degree P (0..MAX_DEGREE).
    iterations: maximum number of full-batch gradient steps.
    lr: initial per-coefficient step size (Rprop) or learning rate (SGD), normalised units.
    tolerance: stop when every per-coefficient Rprop step size is below this (normalised
        units: A and g are dimensionless, b is divided by the data RMS s) — with the
        step halved on every sign change, all coefficients are then pinned to about this.
    optimizer: 'rprop' (default) or 'sgd' (plain gradient descent, kept as the baseline the
        tests compare against; it stops only on `iterations`).
    """

    def __init__(self, degree: int = 2, iterations: int = 4000, lr: float = 1e-3,
                 tolerance: float = 1e-12, optimizer: str = "rprop", prior=None):
        if not 0 <= degree <= MAX_DEGREE:
            raise ValueError(f"degree {degree} is outside 0..{MAX_DEGREE}")
        if optimizer not in OPTIMIZERS:
            raise ValueError(f"optimizer '{optimizer}' is not one of {OPTIMIZERS}")
        self.degree, self.iterations, self.lr = degree, iterations, lr
        self.tolerance, self.optimizer = tolerance, optimizer
        self.prior = prior  # training.models.prior.TriadPrior: fit the maximum a posteriori model

    def fit(self, x_raw: np.ndarray, x_ref: np.ndarray, temp: np.ndarray, seed: int,
            unit: str) -> ThermalFit:
        """Fit the model so that apply_thermal(model, x_raw, temp) ~ x_ref.

        x_raw, x_ref: (N, 3) in `unit`; temp: (N,) °C, NaN allowed (Tn = 0 there).
        Rows with a non-finite x_raw or x_ref value are dropped and counted. The fit is
        deterministic (full batch, fixed start); `seed` seeds torch for reproducibility.
        Raises ValueError when no usable row remains or the descent diverges.
        """
        torch.manual_seed(seed)
        x_raw, x_ref, temp = (np.asarray(a, dtype=np.float64) for a in (x_raw, x_ref, temp))
        keep = np.all(np.isfinite(x_raw), axis=1) & np.all(np.isfinite(x_ref), axis=1)
        if not keep.any():
            raise ValueError("no row with finite raw and reference values")
        x_raw, x_ref, temp = x_raw[keep], x_ref[keep], temp[keep]
        if self.prior is not None:  # the population's basis: it carries what the data do not
            degree, t0, ts = self.prior.degree, self.prior.t0, self.prior.ts
        else:
            norm = temperature_normalisation(temp)
            degree = self.degree if norm is not None else 0
            t0, ts = norm if norm is not None else (DEFAULT_T0, DEFAULT_TS)
        model, history, converged, posterior = self._descend(x_raw, x_ref, temp, degree, t0, ts)
        return ThermalFit(
            model=model, loss_history=tuple(history), iterations=len(history),
            converged=converged, rms_before=_rms(x_raw - x_ref),
            rms_after=_rms(apply_thermal(model, x_raw, temp) - x_ref),
            rows_used=int(keep.sum()), rows_dropped=int((~keep).sum()), unit=unit, posterior_cov=posterior)

    def _descend(self, x_raw, x_ref, temp, degree, t0, ts):
        """Gradient descent on normalised data; returns (model, loss history, converged, the
        posterior covariance of θ with a prior or None)."""
        # Scale s: RMS of all raw and reference values, so u = x/s is O(1) for gyro
        # (~0.01-1 rad/s), acc (~10 m/s²) and mag (~50 µT) alike; loss = MSE / s².
        s = _rms(np.concatenate([x_raw, x_ref])) or 1.0
        u = torch.from_numpy(x_raw / s)
        v = torch.from_numpy(x_ref / s)
        tn = torch.from_numpy(normalised_temperature(temp, t0, ts))
        vand = torch.stack([tn ** k for k in range(degree + 1)], dim=1)
        params = self._initial_parameters(x_raw, x_ref, s, degree)
        a6, g, beta = params
        prior_loss = self._prior_loss(s, degree, u.shape[0])
        if prior_loss is not None:  # start at the population mean
            with torch.no_grad():
                for p, start in zip(params, _unflatten(torch.from_numpy(self._normalised_prior(s)[0]), degree)):
                    if p is not None:
                        p.copy_(start)
        optimiser = self._optimiser([p for p in params if p is not None])
        history, converged = [], False
        for _ in range(self.iterations):
            optimiser.zero_grad()
            loss = torch.mean((_model_torch(a6, g, beta, u, vand) - v) ** 2)
            if prior_loss is not None:
                loss = loss + prior_loss(a6, g, beta)
            loss.backward()
            optimiser.step()
            history.append(loss.item())
            if not np.isfinite(history[-1]):
                raise ValueError(f"fit diverged at iteration {len(history)} (lr={self.lr} "
                                 f"too large for {self.optimizer})")
            if self._converged(optimiser):
                converged = True
                break
        posterior = None if prior_loss is None else self._posterior_cov(a6, g, beta, u, v, vand, prior_loss, s)
        return _to_model(a6, g, beta, s, degree, t0, ts), history, converged, posterior

    def _posterior_cov(self, a6, g, beta, u, v, vand, prior_loss, s: float) -> np.ndarray:
        """Covariance of θ under the prior by Laplace's approximation: the loss is 2w · (negative log
        posterior), w = σ_n² / (3N), so the covariance is 2w · H⁻¹ (H the loss's Hessian at the
        optimum); the b part scaled back by s."""
        degree = g.shape[1] if g is not None else 0
        flat = torch.cat([a6.detach()] + ([g.detach().reshape(-1)] if g is not None else [])
                         + [beta.detach().reshape(-1)])

        def total(theta):
            a, gg, b = _unflatten(theta, degree)
            return torch.mean((_model_torch(a, gg, b, u, vand) - v) ** 2) + prior_loss(a, gg, b)
        hessian = torch.autograd.functional.hessian(total, flat).numpy()
        weight = float(self._normalised_prior(s)[2]) ** 2 / (3.0 * u.shape[0])
        scale = np.ones(len(flat))
        scale[6 + 3 * degree:] = s
        return 2.0 * weight * np.linalg.pinv(hessian) * np.outer(scale, scale)

    def _normalised_prior(self, s: float) -> tuple[np.ndarray, np.ndarray, float]:
        """(mean, σ, noise σ_n) of the prior in the descent's units (b and σ_n divided by s)."""
        mean, sigma = self.prior.mean.copy(), self.prior.sigma.copy()
        b = slice(6 + 3 * self.prior.degree, None)
        mean[b], sigma[b] = mean[b] / s, sigma[b] / s
        return mean, sigma, self.prior.noise / s

    def _prior_loss(self, s: float, degree: int, rows: int):
        """The prior's term of the loss, a function of (a6, g, beta), or None without a prior:
        σ_n² / (3N) · Σ ((θ − μ) / σ)² in the descent's units (module training.models.prior)."""
        if self.prior is None:
            return None
        mean, sigma, noise = (torch.as_tensor(v) for v in self._normalised_prior(s))
        weight = noise ** 2 / (3.0 * rows)

        def loss(a6, g, beta):
            parts = [a6] + ([g.reshape(-1)] if g is not None else []) + [beta.reshape(-1)]
            return weight * torch.sum(((torch.cat(parts) - mean) / sigma) ** 2)
        return loss

    @staticmethod
    def _initial_parameters(x_raw, x_ref, s, degree):
        """Start at A = I, g = 0 and b = [mean(x_raw - x_ref), 0, ...] per axis: the
        least-squares bias of a pure offset model, which is the model at A = I, G = 1."""
        a6 = torch.tensor([1.0, 0.0, 0.0, 1.0, 0.0, 1.0], dtype=torch.float64, requires_grad=True)
        g = torch.zeros((3, degree), dtype=torch.float64, requires_grad=True) if degree else None
        beta0 = np.zeros((3, degree + 1))
        beta0[:, 0] = np.mean(x_raw - x_ref, axis=0) / s
        beta = torch.tensor(beta0, dtype=torch.float64, requires_grad=True)
        return a6, g, beta

    def _optimiser(self, params):
        """Rprop: sign-based per-parameter adaptive step sizes (Riedmiller & Braun 1993,
        'A direct adaptive method for faster backpropagation learning: the RPROP
        algorithm'), or plain SGD as the baseline."""
        if self.optimizer == "sgd":
            return torch.optim.SGD(params, lr=self.lr)
        return torch.optim.Rprop(params, lr=self.lr, step_sizes=RPROP_STEP_BOUNDS)

    def _converged(self, optimiser) -> bool:
        """True when every Rprop per-coefficient step size is below `tolerance`."""
        if self.optimizer != "rprop":
            return False
        steps = [optimiser.state[p]["step_size"] for p in optimiser.param_groups[0]["params"]]
        return all(float(st.max()) < self.tolerance for st in steps)


def _unflatten(flat: torch.Tensor, degree: int) -> tuple:
    """(a6, g or None, beta) from θ in the order of training.models.prior (a6, g, b)."""
    g = flat[6:6 + 3 * degree].reshape(3, degree) if degree else None
    return flat[:6], g, flat[6 + 3 * degree:].reshape(3, degree + 1)


def _to_model(a6, g, beta, s, degree, t0, ts) -> ThermalModel:
    """ThermalModel from the fitted normalised parameters (b = s * beta)."""
    a = _symmetric(a6.detach()).numpy()
    gg = np.zeros((3, 0)) if g is None else g.detach().numpy()
    return ThermalModel(True, t0, ts, degree, a, gg, beta.detach().numpy() * s)


def _rms(a: np.ndarray) -> float:
    """Root mean square over all entries of `a`."""
    return float(np.sqrt(np.mean(np.square(a))))
