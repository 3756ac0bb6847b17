"""PSO-BP gyro bias model b(T, dT/dt) and its fitter (particle swarm, then back-propagation).

Model (MEMS-gyro temperature compensation by a PSO-optimised BP network, as in the PSO-BP
papers: per axis a 2-H-1 network, tansig hidden layer, linear output; inputs temperature and
its rate of change, both min-max normalised to [-1, 1] with the training ranges):

    u0 = 2 (T - t_min) / (t_max - t_min) - 1,   u1 = 2 (r - r_min) / (r_max - r_min) - 1
    b_i = b2[i] + sum_j w2[i][j] tanh(w1[i][j][0] u0 + w1[i][j][1] u1 + b1[i][j])   [rad/s]

T and r are clamped to the training ranges [t_min, t_max] and [r_min, r_max] before they are
normalised, so the networks are never evaluated outside what they were fitted on (Python's
`clamp_inputs=False` skips that for the source's form; in C the `clamp` argument of
ImuPsoBpEvaluate, set by the FMU parameter `psobp_clamp`, makes the same choice).

The output normalisation of the training targets is folded into w2, b2, so the stored model
gives rad/s directly. `sources/ImuPsoBp.c` evaluates the identical formula in the identical
order, and runs the identical causal temperature-rate estimator (`temperature_rate`).

Two modes (block entry 0), same network, same inputs:
  MODE_FULL      the paper's model: b is the whole gyro bias, trained on gyr - ref_gyr of the
                 raw gyro; corrected rate = gyr_raw - b.
  MODE_RESIDUAL  the hybrid the product ships: b is the bias left after the gain/bias
                 polynomial B(T) (training/models/thermal.py), trained on gyr_compensated - ref_gyr;
                 corrected rate = apply_thermal(gyr_raw) - b, i.e. the network output is added
                 on top of the polynomial bias. It captures the warm-up (dT/dt) term the
                 polynomial cannot; outside the training range the tansig units saturate at a
                 small residual and the polynomial carries the extrapolation. Its output is
                 scaled per axis by s in [0, 1] chosen by blocked cross-validation on the
                 training windows (`output_shrinkage`) and folded into w2, b2: s = 0 when the
                 residual holds nothing the network predicts out of block (then b = 0 and the
                 hybrid is the polynomial alone).

Fit: particle-swarm optimisation of the initial weights and thresholds (Kennedy & Eberhart
1995; inertia weight decreasing linearly, Shi & Eberhart 1998), fitness = variance of
(predicted - measured) bias, then full-batch back-propagation (Rprop, Riedmiller & Braun
1993) from the best particle. `use_pso=False` gives plain BP from uniform random weights,
same network, same BP budget and stopping rule. `fit_gyro_residual_psobp` is the entry of
the chain's training (MODE_RESIDUAL), `residual_psobp_wins` the rule for `enable_psobp`.

Training targets: static samples (|ref_gyr| <= rest_rad_s), measured bias = gyr - ref_gyr,
averaged over non-overlapping `window_s` windows (with the window means of T and of the
estimated rate) to remove white noise.

Source form vs product (docs/thermal_models.md "Source form vs product"). The source (issue 4)
leaves open or does not make several choices this fitter makes; each is a switch whose default is
the product's choice, and `SOURCE_FORM` sets them all to the source's form:
  window_s       10 s window-mean targets; None = single static samples (the source's targets)
  pso_clamp      PSO velocity clamp and position box; False = the plain update, unbounded
  ls_threshold   output threshold set to its least-squares value after PSO; False = as the swarm left it
  bp_rule        "rprop" (Rprop); "gd" = plain gradient descent, step lr
  early_stop     patience stop; False = the whole epoch budget
  clamp_inputs   (evaluate_psobp / apply_psobp) inputs clamped to the training ranges; False = not
`ADDITIONS` orders them as the comparison adds them one at a time, `cumulative_forms` gives the
rows from the source's form to MODE_FULL with the defaults ("PSO-BP (a)"). MODE_RESIDUAL (the
product, "poly + PSO-BP (b)") adds two things at once: the network fits the residual of the
polynomial B(T), and its output is shrunk by the inner validation.
"""
from __future__ import annotations

import time
import inspect
from dataclasses import dataclass, replace

import numpy as np
import torch

from training.runtime import load_runtime, pointer

#: Compile-time maximum hidden size (IMU_PSOBP_MAX_HIDDEN in sources/ImuPsoBp.h).
MAX_HIDDEN = 16
#: Block entry 0 (sources/ImuPsoBp.h ImuPsoBpMode): off (zero bias), full bias, residual bias.
MODE_OFF, MODE_FULL, MODE_RESIDUAL = 0, 1, 2
#: The modes by name, as the artefact stores them.
MODE_NAMES = {MODE_OFF: "off", MODE_FULL: "full", MODE_RESIDUAL: "residual"}
#: Block layout (sources/ImuPsoBp.h): header, then per axis w1 (2 MAX), b1 (MAX), w2 (MAX), b2.
HEADER = 7
AXIS_BLOCK = 4 * MAX_HIDDEN + 1
BLOCK_SIZE = HEADER + 3 * AXIS_BLOCK
#: Smallest normalisation spans: a near-isothermal log would otherwise give huge u0 / u1.
MIN_TEMP_SPAN_C = 1.0
MIN_RATE_SPAN_C_S = 1e-3
#: Rprop step-size bounds (normalised weights are O(1)).
RPROP_STEP_BOUNDS = (1e-9, 1.0)
#: BP step rules: Rprop (the product) and plain gradient descent theta <- theta - lr grad (the source).
BP_RULES = ("rprop", "gd")
#: Meaning of the negative return codes of ImuBatchPsoBp* (ImuBatchPsoBp.c).
ERROR_CODES = {-1: "an array pointer is NULL", -2: f"block is not {BLOCK_SIZE} valid doubles"}


# ----------------------------------------------------------------------------- the model


@dataclass(frozen=True, eq=False)
class PsoBpModel:
    """Trained PSO-BP bias model (see the module docstring for the formula).

    mode: MODE_OFF (zero bias), MODE_FULL or MODE_RESIDUAL (module docstring).
    hidden: H, 1..MAX_HIDDEN. tau_s: rate low-pass time constant [s].
    t_min, t_max [°C], r_min, r_max [°C/s]: normalisation ranges (min < max).
    w1: (3, H, 2) [1]; b1: (3, H) [1]; w2: (3, H) [rad/s]; b2: (3,) [rad/s].
    """

    mode: int
    hidden: int
    tau_s: float
    t_min: float
    t_max: float
    r_min: float
    r_max: float
    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    b2: np.ndarray

    def __post_init__(self):
        if self.mode not in (MODE_OFF, MODE_FULL, MODE_RESIDUAL):
            raise ValueError(f"mode {self.mode} is not one of {MODE_OFF}, {MODE_FULL}, {MODE_RESIDUAL}")
        object.__setattr__(self, "mode", int(self.mode))
        h = int(self.hidden)
        if h != self.hidden or not 1 <= h <= MAX_HIDDEN:
            raise ValueError(f"hidden size {self.hidden} is not an integer in 1..{MAX_HIDDEN}")
        if not (self.tau_s > 0 and self.t_min < self.t_max and self.r_min < self.r_max):
            raise ValueError("need tau_s > 0, t_min < t_max and r_min < r_max")
        object.__setattr__(self, "hidden", h)
        for name, shape in (("w1", (3, h, 2)), ("b1", (3, h)), ("w2", (3, h)), ("b2", (3,))):
            a = np.array(getattr(self, name), dtype=np.float64)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise ValueError(f"'{name}' must be finite with shape {shape}, got {a.shape}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def enabled(self) -> bool:
        """True unless the mode is MODE_OFF."""
        return self.mode != MODE_OFF

    def to_block(self) -> list[float]:
        """The flat BLOCK_SIZE-long block of sources/ImuPsoBp.h (weights zero-padded to MAX_HIDDEN)."""
        head = [float(self.mode), float(self.hidden), self.tau_s,
                self.t_min, self.t_max, self.r_min, self.r_max]
        axes = []
        for i in range(3):
            w1 = np.zeros((MAX_HIDDEN, 2))
            w1[:self.hidden] = self.w1[i]
            b1, w2 = np.zeros(MAX_HIDDEN), np.zeros(MAX_HIDDEN)
            b1[:self.hidden], w2[:self.hidden] = self.b1[i], self.w2[i]
            axes.append(np.concatenate([w1.ravel(), b1, w2, [self.b2[i]]]))
        return [float(v) for v in head] + [float(v) for v in np.concatenate(axes)]

    @classmethod
    def from_block(cls, block) -> "PsoBpModel":
        """Inverse of `to_block`; ValueError on a wrong length, mode, size or padding."""
        v = np.asarray(block, dtype=np.float64)
        if v.shape != (BLOCK_SIZE,):
            raise ValueError(f"block has shape {v.shape}, expected ({BLOCK_SIZE},)")
        if v[0] not in (MODE_OFF, MODE_FULL, MODE_RESIDUAL):
            raise ValueError(f"mode is {v[0]}, expected {MODE_OFF}, {MODE_FULL} or {MODE_RESIDUAL}")
        if v[1] not in range(1, MAX_HIDDEN + 1):
            raise ValueError(f"hidden size {v[1]} is not an integer in 1..{MAX_HIDDEN}")
        h = int(v[1])
        axes = v[HEADER:].reshape(3, AXIS_BLOCK)
        w1 = axes[:, :2 * MAX_HIDDEN].reshape(3, MAX_HIDDEN, 2)
        b1 = axes[:, 2 * MAX_HIDDEN:3 * MAX_HIDDEN]
        w2 = axes[:, 3 * MAX_HIDDEN:4 * MAX_HIDDEN]
        if np.any(w1[:, h:] != 0) or np.any(b1[:, h:] != 0) or np.any(w2[:, h:] != 0):
            raise ValueError(f"weights above hidden size {h} are not zero")
        return cls(int(v[0]), h, *v[2:7], w1[:, :h], b1[:, :h], w2[:, :h], axes[:, -1])

    def to_json(self) -> dict:
        """The model as the artefact stores it (training.artefact, format 2): named parts in their
        units, no C layout. w1, b1 act on the temperature and its rate normalised to [-1, 1] over
        their ranges; w2 [rad/s] and b2 [rad/s] give the bias of each axis."""
        return {"mode": MODE_NAMES[self.mode], "hidden": self.hidden, "rate_time_constant_s": float(self.tau_s),
                "temperature_range_c": [float(self.t_min), float(self.t_max)],
                "temperature_rate_range_c_per_s": [float(self.r_min), float(self.r_max)],
                "w1": self.w1.tolist(), "b1": self.b1.tolist(), "w2_rad_s": self.w2.tolist(),
                "b2_rad_s": self.b2.tolist()}

    @classmethod
    def from_json(cls, doc: dict) -> "PsoBpModel":
        """Inverse of `to_json`; ValueError naming the first bad entry."""
        if not isinstance(doc, dict) or doc.get("mode") not in MODE_NAMES.values():
            raise ValueError(f"a PSO-BP stage must be an object with mode one of {sorted(MODE_NAMES.values())}")
        try:
            (t_min, t_max), (r_min, r_max) = doc["temperature_range_c"], doc["temperature_rate_range_c_per_s"]
            return cls({v: k for k, v in MODE_NAMES.items()}[doc["mode"]], doc["hidden"],
                       float(doc["rate_time_constant_s"]), float(t_min), float(t_max), float(r_min), float(r_max),
                       doc["w1"], doc["b1"], doc["w2_rad_s"], doc["b2_rad_s"])
        except (KeyError, TypeError) as e:
            raise ValueError(f"a PSO-BP stage lacks or mistypes {e}") from None


def temperature_rate(t: np.ndarray, temp: np.ndarray, tau_s: float,
                     initial_temp: float) -> tuple[np.ndarray, np.ndarray]:
    """Causal temperature estimate: (held temperature [°C], filtered rate [°C/s]), each (N,).

    First-order low-pass of the backward difference, exact for variable steps
    (ImuPsoBpUpdate in C, same order of operations):
        d = (T_k - T_prev) / (t_k - t_prev),  a = 1 - exp(-(t_k - t_prev) / tau),  r += a (d - r)
    A NaN temperature (or a non-increasing time) leaves the state unchanged (the last finite
    temperature is held); before the first finite one T = initial_temp and r = 0. On a ramp
    T = T0 + s t from t0 the rate is s (1 - exp(-(t - t0) / tau)) exactly.
    """
    t = np.asarray(t, dtype=np.float64)
    temp = np.asarray(temp, dtype=np.float64)
    held, rate = np.empty_like(t), np.empty_like(t)
    started, t_prev, x_prev, r = False, 0.0, float(initial_temp), 0.0
    for k in range(t.shape[0]):
        tk, xk = float(t[k]), float(temp[k])
        if xk == xk:  # not NaN
            if not started:
                started, t_prev, x_prev, r = True, tk, xk, 0.0
            elif tk - t_prev > 0.0:
                dt = tk - t_prev
                alpha = 1.0 - np.exp(-dt / tau_s)
                r += alpha * ((xk - x_prev) / dt - r)
                t_prev, x_prev = tk, xk
        held[k], rate[k] = x_prev, r
    return held, rate


def evaluate_psobp(model: PsoBpModel, temp: np.ndarray, rate: np.ndarray,
                   clamp_inputs: bool = True) -> np.ndarray:
    """Bias (N, 3) [rad/s] of the networks at temperatures (N,) [°C] and rates (N,) [°C/s], each
    clamped to the training range [t_min, t_max], [r_min, r_max] first (the networks are never
    extrapolated). Same operation order as ImuPsoBpEvaluate in C. clamp_inputs=False skips the
    clamp (the source's form; in C the `clamp` argument, the FMU parameter `psobp_clamp`)."""
    temp = np.asarray(temp, dtype=np.float64)
    rate = np.asarray(rate, dtype=np.float64)
    if clamp_inputs:
        temp = np.clip(temp, model.t_min, model.t_max)
        rate = np.clip(rate, model.r_min, model.r_max)
    if not model.enabled:
        return np.zeros((temp.shape[0], 3))
    u0 = 2.0 * (temp - model.t_min) / (model.t_max - model.t_min) - 1.0
    u1 = 2.0 * (rate - model.r_min) / (model.r_max - model.r_min) - 1.0
    out = np.empty((temp.shape[0], 3))
    for i in range(3):
        acc = np.full_like(u0, model.b2[i])
        for j in range(model.hidden):
            acc = acc + model.w2[i, j] * np.tanh(model.w1[i, j, 0] * u0 + model.w1[i, j, 1] * u1
                                                 + model.b1[i, j])
        out[:, i] = acc
    return out


def apply_psobp(model: PsoBpModel, t: np.ndarray, temp: np.ndarray,
                clamp_inputs: bool = True) -> np.ndarray:
    """Causal bias prediction (N, 3) [rad/s] over a series: rate estimator, then the networks.
    t (N,) [s] increasing; temp (N,) [°C], NaN allowed (last finite value held); clamp_inputs
    as in `evaluate_psobp`."""
    held, rate = temperature_rate(t, temp, model.tau_s, 0.5 * (model.t_min + model.t_max))
    return evaluate_psobp(model, held, rate, clamp_inputs)


def correct_gyro_psobp(model: PsoBpModel, t: np.ndarray, gyr: np.ndarray,
                       temp: np.ndarray) -> np.ndarray:
    """Corrected rates gyr - b (N, 3) [rad/s] (ImuPsoBpCorrect in C). gyr (N, 3) [rad/s] is the
    raw gyro for MODE_FULL and the thermally compensated gyro (apply_thermal) for
    MODE_RESIDUAL; t (N,) [s], temp (N,) [°C] as in `apply_psobp`."""
    return np.asarray(gyr, dtype=np.float64) - apply_psobp(model, t, temp)


def correct_gyro_psobp_c(model: PsoBpModel, t: np.ndarray, gyr: np.ndarray,
                         temp: np.ndarray) -> np.ndarray:
    """`correct_gyro_psobp` computed by the C runtime (ImuBatchPsoBpCorrect), (N, 3) [rad/s]."""
    block = np.ascontiguousarray(model.to_block(), dtype=np.float64)
    t = np.ascontiguousarray(t, dtype=np.float64)
    temp = np.ascontiguousarray(temp, dtype=np.float64)
    gyr = np.ascontiguousarray(gyr, dtype=np.float64)
    if t.ndim != 1 or temp.shape != t.shape or gyr.shape != (t.shape[0], 3):
        raise ValueError(f"need t, temp (N,) and gyr (N, 3), got {t.shape}, {temp.shape}, {gyr.shape}")
    out = np.empty_like(gyr)
    code = load_runtime().ImuBatchPsoBpCorrect(pointer(block), block.size, t.shape[0], pointer(t), pointer(temp),
                                               pointer(gyr), pointer(out))
    if code != 0:
        raise ValueError(f"C runtime rejected the PSO-BP input (code {code}): "
                         f"{ERROR_CODES.get(code, 'unknown error')}")
    return out


def _c_call(name: str, model: PsoBpModel, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Call ImuBatchPsoBp<name>(block, nBlock, n, a, b, out) of the runtime library."""
    fn = getattr(load_runtime(), f"ImuBatchPsoBp{name}")
    block = np.ascontiguousarray(model.to_block(), dtype=np.float64)
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"inputs must be two (N,) arrays, got {a.shape} and {b.shape}")
    out = np.empty((a.shape[0], 3))
    code = fn(pointer(block), block.size, a.shape[0], pointer(a), pointer(b), pointer(out))
    if code != 0:
        raise ValueError(f"C runtime rejected the PSO-BP input (code {code}): "
                         f"{ERROR_CODES.get(code, 'unknown error')}")
    return out


def predict_psobp_c(model: PsoBpModel, t: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """`apply_psobp` computed by the C runtime (ImuBatchPsoBpPredict), (N, 3) [rad/s]."""
    return _c_call("Predict", model, t, temp)


def evaluate_psobp_c(model: PsoBpModel, temp: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """`evaluate_psobp` computed by the C runtime (ImuBatchPsoBpEvaluate), (N, 3) [rad/s]."""
    return _c_call("Evaluate", model, temp, rate)


# ----------------------------------------------------------------------------- PSO


def inertia_weight(k: int, iterations: int, w_begin: float = 0.9, w_end: float = 0.4) -> float:
    """Linearly decreasing inertia (Shi & Eberhart 1998): w_k = w_begin - (w_begin - w_end) k / (K - 1)."""
    if iterations <= 1:
        return w_begin
    return w_begin - (w_begin - w_end) * k / (iterations - 1)


def pso_step(x, v, pbest, gbest, w, c1, c2, r1, r2, vmax):
    """One swarm update (Kennedy & Eberhart 1995, with inertia w), (P, D) arrays:
        v <- clip(w v + c1 r1 (pbest - x) + c2 r2 (gbest - x), -vmax, vmax),  x <- x + v.
    Returns (x_new, v_new); gbest is (D,), r1 and r2 are (P, D) uniform [0, 1) draws."""
    v_new = np.clip(w * v + c1 * r1 * (pbest - x) + c2 * r2 * (gbest - x), -vmax, vmax)
    return x + v_new, v_new


@dataclass(frozen=True)
class PsoResult:
    """Best position (D,), its fitness, and the global-best fitness after each iteration."""

    best: np.ndarray
    fitness: float
    history: tuple[float, ...]


def pso_minimise(fitness, dim: int, rng: np.random.Generator, particles: int = 30,
                 iterations: int = 50, bound: float = 3.0, velocity_fraction: float = 0.2,
                 w_begin: float = 0.9, w_end: float = 0.4, c1: float = 2.0,
                 c2: float = 2.0, clamp: bool = True) -> PsoResult:
    """Minimise fitness((P, D) positions) -> (P,) over the box [-bound, bound]^D.

    Start: positions uniform in [-1, 1] (the usual initial-weight range), velocities 0;
    velocity clamp vmax = velocity_fraction * 2 bound; positions clipped to the box.
    clamp=False: no velocity clamp and no box (the plain update; bound and velocity_fraction unused).
    """
    vmax = velocity_fraction * 2.0 * bound if clamp else np.inf
    x = rng.uniform(-1.0, 1.0, (particles, dim))
    v = np.zeros_like(x)
    f = fitness(x)
    pbest, pbest_f = x.copy(), f.copy()
    g = int(np.argmin(pbest_f))
    history = []
    for k in range(iterations):
        r1, r2 = rng.random((particles, dim)), rng.random((particles, dim))
        x, v = pso_step(x, v, pbest, pbest[g], inertia_weight(k, iterations, w_begin, w_end),
                        c1, c2, r1, r2, vmax)
        if clamp:
            x = np.clip(x, -bound, bound)
        f = fitness(x)
        better = f < pbest_f
        pbest[better], pbest_f[better] = x[better], f[better]
        g = int(np.argmin(pbest_f))
        history.append(float(pbest_f[g]))
    return PsoResult(pbest[g].copy(), float(pbest_f[g]), tuple(history))


# ----------------------------------------------------------------------------- network fit


def _unpack(theta: np.ndarray, hidden: int):
    """(..., 4H+1) parameter vectors -> w1 (..., H, 2), b1 (..., H), w2 (..., H), b2 (...)."""
    w1 = theta[..., :2 * hidden].reshape(*theta.shape[:-1], hidden, 2)
    return (w1, theta[..., 2 * hidden:3 * hidden], theta[..., 3 * hidden:4 * hidden],
            theta[..., 4 * hidden])


def swarm_predict(theta: np.ndarray, u: np.ndarray, hidden: int) -> np.ndarray:
    """Outputs (P, M) of P networks (P, 4H+1) at normalised inputs u (M, 2)."""
    w1, b1, w2, b2 = _unpack(theta, hidden)
    h = np.tanh(np.einsum("phk,mk->pmh", w1, u) + b1[:, None, :])
    return np.einsum("pmh,ph->pm", h, w2) + b2[:, None]


def variance_fitness(theta: np.ndarray, u: np.ndarray, y: np.ndarray, hidden: int) -> np.ndarray:
    """PSO fitness (P,): variance over the M samples of (predicted - measured) bias."""
    return np.var(swarm_predict(theta, u, hidden) - y[None, :], axis=1)


@dataclass(frozen=True)
class BpResult:
    """Trained parameter vectors (3, 4H+1), epochs run, per-axis MSE before and after
    [normalised²]."""

    theta: np.ndarray
    epochs: int
    loss_start: tuple[float, float, float]
    loss_end: tuple[float, float, float]


def _batched_losses(theta: torch.Tensor, u: torch.Tensor, y: torch.Tensor, hidden: int) -> torch.Tensor:
    """Per-network MSE (A,) of A networks theta (A, 4H+1) on u (M, 2) and targets y (M, A)."""
    w1, b1, w2, b2 = _unpack(theta, hidden)
    h = torch.tanh(torch.einsum("ahk,mk->amh", w1, u) + b1[:, None, :])
    pred = torch.einsum("amh,ah->am", h, w2) + b2[:, None]
    return torch.mean((pred - y.T) ** 2, dim=1)


def backpropagate(theta0: np.ndarray, u: np.ndarray, y: np.ndarray, hidden: int, epochs: int,
                  lr: float, patience: int, tolerance: float, rule: str = "rprop",
                  early_stop: bool = True) -> BpResult:
    """Full-batch BP of the three axis networks (independent weights, trained together on the
    summed MSE), from theta0 (3, 4H+1); u (M, 2) inputs, y (M, 3) targets.

    rule: "rprop" (Rprop, initial step lr) or "gd" (plain gradient descent, step lr).
    Stops after `epochs`, or (early_stop) when the summed loss fell by less than `tolerance`
    (relative) over the last `patience` epochs.
    """
    if rule not in BP_RULES:
        raise ValueError(f"BP rule {rule!r} is not one of {BP_RULES}")
    theta = torch.tensor(theta0, dtype=torch.float64, requires_grad=True)
    ut, yt = torch.from_numpy(u), torch.from_numpy(y)
    opt = (torch.optim.Rprop([theta], lr=lr, step_sizes=RPROP_STEP_BOUNDS) if rule == "rprop"
           else torch.optim.SGD([theta], lr=lr))
    losses, first = [], None
    for _ in range(epochs):
        opt.zero_grad()
        per_axis = _batched_losses(theta, ut, yt, hidden)
        first = per_axis.detach().numpy().copy() if first is None else first
        loss = per_axis.sum()
        loss.backward()
        opt.step()
        losses.append(loss.item())
        if early_stop and len(losses) > patience and losses[-patience - 1] - losses[-1] < tolerance * losses[-patience - 1]:
            break
    with torch.no_grad():
        final = _batched_losses(theta, ut, yt, hidden).numpy()
    return BpResult(theta.detach().numpy().copy(), len(losses), tuple(map(float, first)),
                    tuple(map(float, final)))


def bias_targets(t, gyr, ref_gyr, temp, tau_s: float, window_s: float | None, rest_rad_s: float):
    """Window-averaged static training targets.

    Runs the causal rate estimator over the whole series, keeps rows with finite gyr, ref_gyr
    and temperature and |ref_gyr| <= rest_rad_s, and averages them over non-overlapping
    windows of window_s [s] (window k holds t0 + k window_s <= t < t0 + (k+1) window_s);
    window_s None keeps the single rows (no averaging).
    Returns (temp (M,) [°C], rate (M,) [°C/s], bias (M, 3) [rad/s]).
    """
    t, temp = np.asarray(t, dtype=np.float64), np.asarray(temp, dtype=np.float64)
    gyr, ref_gyr = np.asarray(gyr, dtype=np.float64), np.asarray(ref_gyr, dtype=np.float64)
    held, rate = temperature_rate(t, temp, tau_s, 0.0)
    keep = (np.all(np.isfinite(gyr), axis=1) & np.all(np.isfinite(ref_gyr), axis=1)
            & np.isfinite(temp) & (np.linalg.norm(np.nan_to_num(ref_gyr), axis=1) <= rest_rad_s))
    if not keep.any():
        raise ValueError("no static row with finite gyro, reference and temperature")
    if window_s is None:
        return temp[keep], rate[keep], gyr[keep] - ref_gyr[keep]
    bins = np.floor((t[keep] - t[keep][0]) / window_s).astype(np.int64)
    _, index, counts = np.unique(bins, return_inverse=True, return_counts=True)

    def mean(a):
        return np.bincount(index, weights=a) / counts

    bias = gyr[keep] - ref_gyr[keep]
    return (mean(temp[keep]), mean(rate[keep]),
            np.column_stack([mean(bias[:, i]) for i in range(3)]))


def _span(lo: float, hi: float, minimum: float) -> tuple[float, float]:
    """(lo, hi) widened symmetrically to at least `minimum`."""
    if hi - lo >= minimum:
        return lo, hi
    c = 0.5 * (lo + hi)
    return c - 0.5 * minimum, c + 0.5 * minimum


@dataclass(frozen=True)
class PsoBpFit:
    """Result of `PsoBpFitter.fit`: the model, wall-clock seconds (total, PSO, BP), process CPU
    seconds (total; time.process_time, insensitive to other processes' load), BP epochs, per
    axis PSO best fitness and BP start/end MSE [normalised²], training windows used, and for
    `fit_gyro_residual_psobp` the per-axis output shrinkage folded into the model (else None)."""

    model: PsoBpModel
    seconds: float
    cpu_seconds: float
    pso_seconds: float
    bp_seconds: float
    epochs: int
    pso_fitness: tuple[float, float, float] | None
    loss_start: tuple[float, float, float]
    loss_end: tuple[float, float, float]
    windows: int
    shrinkage: tuple[float, float, float] | None = None


class PsoBpFitter:
    """Fits the PSO-BP gyro bias model (or plain BP with use_pso=False).

    hidden: H (1..MAX_HIDDEN, paper 4). tau_s: rate low-pass time constant [s].
    window_s: averaging window of the targets [s]. rest_rad_s: |ref_gyr| bound of a static row.
    mode: MODE_FULL (the paper's whole-bias model) or MODE_RESIDUAL (targets are the bias left
    after the gain/bias polynomial; pass the compensated gyro to `fit`).
    PSO: particles, pso_iterations, inertia (w_begin, w_end), c1, c2, bound (position box),
    velocity_fraction (vmax = fraction * box width).
    BP: epochs (budget), lr (initial Rprop step, or the gradient-descent step), patience and
    tolerance (stopping rule).
    Source-form switches (module docstring; defaults = the product): window_s None (single-sample
    targets), pso_clamp, ls_threshold, bp_rule ("rprop" or "gd"), early_stop.
    """

    def __init__(self, hidden: int = 4, tau_s: float = 10.0, window_s: float | None = 10.0,
                 rest_rad_s: float = 1e-3, mode: int = MODE_FULL, use_pso: bool = True, particles: int = 30,
                 pso_iterations: int = 60, inertia: tuple[float, float] = (0.9, 0.4),
                 c1: float = 2.0, c2: float = 2.0, bound: float = 3.0,
                 velocity_fraction: float = 0.2, epochs: int = 3000, lr: float = 0.01,
                 patience: int = 50, tolerance: float = 1e-3, pso_clamp: bool = True,
                 ls_threshold: bool = True, bp_rule: str = "rprop", early_stop: bool = True):
        if not 1 <= hidden <= MAX_HIDDEN:
            raise ValueError(f"hidden size {hidden} is outside 1..{MAX_HIDDEN}")
        if not (tau_s > 0 and (window_s is None or window_s > 0)):
            raise ValueError("tau_s and window_s must be positive (window_s None: single samples)")
        if bp_rule not in BP_RULES:
            raise ValueError(f"BP rule {bp_rule!r} is not one of {BP_RULES}")
        if mode not in (MODE_FULL, MODE_RESIDUAL):
            raise ValueError(f"mode {mode} is not MODE_FULL ({MODE_FULL}) or MODE_RESIDUAL ({MODE_RESIDUAL})")
        self.mode = mode
        self.hidden, self.tau_s, self.window_s, self.rest_rad_s = hidden, tau_s, window_s, rest_rad_s
        self.use_pso, self.particles, self.pso_iterations = use_pso, particles, pso_iterations
        self.inertia, self.c1, self.c2 = inertia, c1, c2
        self.bound, self.velocity_fraction = bound, velocity_fraction
        self.epochs, self.lr, self.patience, self.tolerance = epochs, lr, patience, tolerance
        self.pso_clamp, self.ls_threshold = pso_clamp, ls_threshold
        self.bp_rule, self.early_stop = bp_rule, early_stop

    def fit(self, t, gyr, ref_gyr, temp, seed: int) -> PsoBpFit:
        """Fit on a static recording: t (N,) [s], gyr and ref_gyr (N, 3) [rad/s], temp (N,)
        [°C]. Same seed, same model. Times include target preparation."""
        start, cpu_start = time.perf_counter(), time.process_time()
        fit = self.fit_windows(*self.targets(t, gyr, ref_gyr, temp), seed)
        return replace(fit, seconds=time.perf_counter() - start,
                       cpu_seconds=time.process_time() - cpu_start)

    def targets(self, t, gyr, ref_gyr, temp) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`bias_targets` with this fitter's tau_s, window_s and rest_rad_s."""
        return bias_targets(t, gyr, ref_gyr, temp, self.tau_s, self.window_s, self.rest_rad_s)

    def fit_windows(self, temp_w, rate_w, bias_w, seed: int) -> PsoBpFit:
        """Fit on window targets (as `targets` returns them): temp_w (M,) [°C], rate_w (M,)
        [°C/s], bias_w (M, 3) [rad/s]. Same seed, same model."""
        start, cpu_start = time.perf_counter(), time.process_time()
        t_min, t_max = _span(float(temp_w.min()), float(temp_w.max()), MIN_TEMP_SPAN_C)
        r_min, r_max = _span(float(rate_w.min()), float(rate_w.max()), MIN_RATE_SPAN_C_S)
        u = np.column_stack([2.0 * (temp_w - t_min) / (t_max - t_min) - 1.0,
                             2.0 * (rate_w - r_min) / (r_max - r_min) - 1.0])
        rng = np.random.default_rng(seed)
        torch.manual_seed(seed)
        lo, hi = bias_w.min(axis=0), bias_w.max(axis=0)
        centre, scale = 0.5 * (lo + hi), np.maximum(0.5 * (hi - lo), 1e-12)
        y = (bias_w - centre) / scale                                   # (M, 3) in [-1, 1]
        t0 = time.perf_counter()
        starts = [self._start(u, y[:, i], rng) for i in range(3)]
        t1 = time.perf_counter()
        bp = backpropagate(np.array([s[0] for s in starts]), u, y, self.hidden, self.epochs,
                           self.lr, self.patience, self.tolerance, self.bp_rule, self.early_stop)
        t2 = time.perf_counter()
        w1, b1, w2, b2 = _unpack(bp.theta, self.hidden)
        # Fold the output normalisation y = centre + scale y_n into the output layer.
        model = PsoBpModel(self.mode, self.hidden, self.tau_s, t_min, t_max, r_min, r_max, w1, b1,
                           w2 * scale[:, None], b2 * scale + centre)
        return PsoBpFit(model, time.perf_counter() - start, time.process_time() - cpu_start,
                        t1 - t0, t2 - t1, bp.epochs,
                        tuple(s[1] for s in starts) if self.use_pso else None, bp.loss_start,
                        bp.loss_end, int(temp_w.shape[0]))

    def _start(self, u, y, rng) -> tuple[np.ndarray, float]:
        """Initial weights of one axis network and the PSO fitness (NaN for plain BP): the
        PSO best particle, or uniform [-1, 1] draws (plain BP)."""
        dim = 4 * self.hidden + 1
        if not self.use_pso:
            return rng.uniform(-1.0, 1.0, dim), float("nan")
        result = pso_minimise(lambda th: variance_fitness(th, u, y, self.hidden), dim, rng,
                              self.particles, self.pso_iterations, self.bound,
                              self.velocity_fraction, *self.inertia, self.c1, self.c2, self.pso_clamp)
        best = result.best.copy()
        if self.ls_threshold:
            # The variance fitness leaves the output threshold free: take its least-squares value.
            best[-1] += float(np.mean(y - swarm_predict(best[None, :], u, self.hidden)[0]))
        return best, result.fitness


# ----------------------------------------------------------------------------- source form


#: The source's form (issue 4) of every switch (module docstring): single-sample targets, the
#: plain swarm update with no clamp or box, the threshold as the swarm leaves it, plain gradient
#: descent over the whole budget, inputs not clamped.
SOURCE_FORM = {"window_s": None, "pso_clamp": False, "ls_threshold": False, "bp_rule": "gd",
               "early_stop": False, "clamp_inputs": False}
#: The product's additions to the source form, in the order the comparison adds them: (switch,
#: what it adds). Every switch of SOURCE_FORM once.
ADDITIONS = (("window_s", "window-mean targets"),
             ("pso_clamp", "PSO velocity clamp and position box"),
             ("ls_threshold", "least-squares output threshold after PSO"),
             ("bp_rule", "Rprop step rule"),
             ("early_stop", "patience stop"),
             ("clamp_inputs", "inputs clamped to the training ranges"))


def product_form(**overrides) -> dict:
    """The product's value of every SOURCE_FORM switch: PsoBpFitter's defaults (clamp_inputs:
    evaluate_psobp's), with `overrides` (e.g. the harness's window_s) taking precedence."""
    values = {**{k: p.default for k, p in inspect.signature(PsoBpFitter).parameters.items()},
              "clamp_inputs": inspect.signature(evaluate_psobp).parameters["clamp_inputs"].default}
    return {k: overrides.get(k, values[k]) for k in SOURCE_FORM}


def cumulative_forms(**overrides) -> list[tuple[str, dict, bool]]:
    """The rows from the source's form to the product's MODE_FULL fit, additions one at a time:
    (what the row adds, or "" for the source's form; PsoBpFitter switch settings; clamp_inputs).
    The last row is the product's form (`product_form(**overrides)`)."""
    product = product_form(**overrides)
    form, rows = dict(SOURCE_FORM), []
    for switch, added in (("", ""),) + ADDITIONS:
        if switch:
            form[switch] = product[switch]
        fit = {k: v for k, v in form.items() if k != "clamp_inputs"}
        rows.append((added, fit, form["clamp_inputs"]))
    return rows


# ----------------------------------------------------------------------------- chain entry


#: Contiguous blocks of the training windows (time order, equal counts) in the residual fit's
#: inner validation; on the six-plateau protocol they are exactly the four training plateaus.
INNER_FOLDS = 4


def shrink_output(model: PsoBpModel, s: np.ndarray) -> PsoBpModel:
    """`model` with axis i's output scaled by s[i] (3,): w2 and b2 times s, so the stored block
    layout and the C inference stay as they are."""
    s = np.asarray(s, dtype=np.float64)
    return replace(model, w2=model.w2 * s[:, None], b2=model.b2 * s)


def output_shrinkage(fitter: PsoBpFitter, temp_w, rate_w, bias_w, seed: int,
                     folds: int) -> np.ndarray:
    """Per-axis output shrinkage (3,) in [0, 1] by blocked cross-validation on training windows.

    The windows (M, in time order, as `PsoBpFitter.targets` returns them) are cut into `folds`
    contiguous blocks of equal count; for each block k a network fitted on the other blocks
    predicts f_k at block k's windows, whose targets are y_k. s = clip(sum_k <y_k, f_k> /
    sum_k <f_k, f_k>, 0, 1): the least-squares scale of the out-of-block predictions, 0 when
    they do not correlate with the targets (then the hybrid is the polynomial alone).
    """
    if folds < 2 or temp_w.shape[0] < folds:
        raise ValueError(f"need 2 <= folds <= windows, got {folds} folds and {temp_w.shape[0]} windows")
    num, den = np.zeros(3), np.zeros(3)
    for block in np.array_split(np.arange(temp_w.shape[0]), folds):
        rest = np.ones(temp_w.shape[0], dtype=bool)
        rest[block] = False
        model = fitter.fit_windows(temp_w[rest], rate_w[rest], bias_w[rest], seed).model
        f = evaluate_psobp(model, temp_w[block], rate_w[block])
        num += np.sum(f * bias_w[block], axis=0)
        den += np.sum(f * f, axis=0)
    return np.clip(np.divide(num, den, out=np.zeros(3), where=den > 0.0), 0.0, 1.0)


def fit_gyro_residual_psobp(t, gyr_compensated, ref_gyr, temp, seed: int, hidden: int = 4,
                            tau_s: float = 10.0, folds: int = INNER_FOLDS,
                            **settings) -> PsoBpFit:
    """Residual PSO-BP (MODE_RESIDUAL) for the chain's training, output shrunk by an inner
    validation on the given rows only (`output_shrinkage`), folded into w2 and b2.

    t (N,) [s]; gyr_compensated (N, 3) [rad/s] = apply_thermal(gyro model, gyr_raw, temp);
    ref_gyr (N, 3) [rad/s]; temp (N,) [°C]; seed: PSO and torch seed (every fit); hidden: H;
    tau_s: rate low-pass [s]; folds: blocks of the inner validation; settings: further
    PsoBpFitter arguments (window_s, rest_rad_s, particles, ...). The network is fitted on all
    windows; seconds and cpu_seconds include the inner fits, the PSO / BP seconds, epochs and
    losses are those of the final fit.
    """
    start, cpu_start = time.perf_counter(), time.process_time()
    fitter = PsoBpFitter(hidden=hidden, tau_s=tau_s, mode=MODE_RESIDUAL, **settings)
    windows = fitter.targets(t, gyr_compensated, ref_gyr, temp)
    s = output_shrinkage(fitter, *windows, seed, folds)
    fit = fitter.fit_windows(*windows, seed)
    return replace(fit, model=shrink_output(fit.model, s), shrinkage=tuple(map(float, s)),
                   seconds=time.perf_counter() - start,
                   cpu_seconds=time.process_time() - cpu_start)


#: `enable_psobp` needs the hybrid to cut the held-out residual bias RMS by at least this
#: fraction: a smaller gain is within the run-to-run spread of the network fits (±20 % of
#: the residual on the simulated protocol) and does not pay for a second model per sample.
ENABLE_MIN_GAIN = 0.1


@dataclass(frozen=True)
class EnableDecision:
    """`residual_psobp_wins` result: enable flag, held-out RMS of the 10 s window-mean bias
    [rad/s] with the polynomial alone and with polynomial + residual network, held-out windows."""

    enable: bool
    rms_polynomial: float
    rms_hybrid: float
    windows: int


def residual_psobp_wins(t, gyr_compensated, ref_gyr, temp, seed: int, hidden: int = 4,
                        tau_s: float = 10.0, holdout_fraction: float = 1.0 / 3.0,
                        **settings) -> EnableDecision:
    """Decision rule for the default of `enable_psobp`.

    Fits the residual network on the calibration rows with t < t0 + (1 - holdout_fraction)
    span (arguments as in `fit_gyro_residual_psobp`), runs it causally over the whole series
    and compares, on the static held-out rows, the RMS of the window-mean bias of
    gyr_compensated - ref_gyr (polynomial alone) and of that minus the network (hybrid).
    enable = rms_hybrid <= (1 - ENABLE_MIN_GAIN) rms_polynomial. The polynomial was fitted on
    all calibration rows, the network only on the first part: the rule is conservative.
    """
    t = np.asarray(t, dtype=np.float64)
    gyr_compensated = np.asarray(gyr_compensated, dtype=np.float64)
    if not 0.0 < holdout_fraction < 1.0:
        raise ValueError(f"holdout_fraction {holdout_fraction} is not in (0, 1)")
    span = t[-1] - t[0]
    train = t < t[0] + (1.0 - holdout_fraction) * span
    fit = fit_gyro_residual_psobp(t[train], gyr_compensated[train], ref_gyr[train], temp[train],
                                  seed, hidden, tau_s, **settings)
    hybrid = correct_gyro_psobp(fit.model, t, gyr_compensated, temp)
    window_s = settings.get("window_s", 10.0)
    rest = settings.get("rest_rad_s", 1e-3)
    held = ~train
    before = bias_targets(t[held], gyr_compensated[held], ref_gyr[held], temp[held], tau_s,
                          window_s, rest)[2]
    after = bias_targets(t[held], hybrid[held], ref_gyr[held], temp[held], tau_s, window_s, rest)[2]
    rms_p, rms_h = float(np.sqrt(np.mean(before ** 2))), float(np.sqrt(np.mean(after ** 2)))
    return EnableDecision(rms_h <= (1.0 - ENABLE_MIN_GAIN) * rms_p, rms_p, rms_h,
                          int(before.shape[0]))
