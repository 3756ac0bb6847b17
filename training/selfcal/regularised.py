"""Regularised least squares: fit what the data determine, hold the rest at nominal, say which.

Every parameter θ_i has a nominal value θ0_i (gain 1, no cross-axis term, no bias) and a prior
width σ_i: how far a sensor of the class may be from nominal. The data residuals r_k(θ) are divided
by their noise σ_g (one per residual group: gravity norm, face directions, rest-to-rest directions,
turn angles ...). In the whitened parameters u = S⁻¹(θ − θ0), S = diag(σ_i), the data information is
H = S Jᵀ J S; its eigenvectors are the parameter combinations, its eigenvalues λ how well the data
pin each down relative to the prior (the data's standard error along it is σ/√λ).

The fit minimises

    ‖r(θ)‖² + ‖P_w S⁻¹ (θ − θ0)‖²

where P_w projects on the *weak* combinations, λ < DETERMINED_INFO: a combination the data pin down
better than half its prior width is fitted from the data alone (no pull towards nominal, so a gain 31 %
off nominal that the data determine to ±3 % comes out at 31 %), a weaker one is held near nominal by
its prior (maximum a posteriori; a Gaussian prior, Tikhonov regularisation in the whitened space).
Nothing is refused: a model is never thrown away because one of its parameters is weak.

The noise σ_g of each group is re-estimated from its residuals (variance components: the group's
weighted sum of squares over its degrees of freedom minus its share of the fitted parameters, the sum of
its rows' leverages), floored at the group's physical floor; a group too small to estimate its noise
keeps the floor. Standard errors are the posterior's, cov = S (H + P_w)⁻¹ S. A parameter whose
standard error exceeds HELD_SHARE of its prior width is reported as held by the prior: the recording
does not determine it. Levenberg-Marquardt, deterministic (no random numbers).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

#: A combination of parameters whose data information is at least this (in units of the prior's:
#: the data's standard error along it is at most 1/√4 = half the prior width) is fitted from the
#: data alone; a weaker one keeps its prior.
DETERMINED_INFO = 4.0
#: A parameter whose posterior standard error is above this share of its prior width is "held at
#: nominal by the prior": the data narrowed its uncertainty by less than a factor 2.
HELD_SHARE = 0.5
#: Levenberg-Marquardt: iterations per solve, relative cost decrease that counts as converged.
LM_ITERATIONS = 60
LM_TOLERANCE = 1e-13
#: Re-estimations of the group noises and the weak subspace (each followed by a solve).
OUTER_ITERATIONS = 4
#: Fewest degrees of freedom a group needs left (after its share of the parameters) to estimate its noise.
MIN_GROUP_DOF = 1.0


@dataclass(frozen=True)
class Group:
    """One kind of residual: name, the rows of the residual vector it owns (index array), the dof each
    row carries (1; 2/3 for the 3 components of a unit-vector difference; times the row's weight w when
    the caller scales the row by √w, e.g. 1/size of its pose group), its noise floor and starting
    noise [the residual's unit]; fixed: keep the starting noise (known from elsewhere, e.g. the
    repeatability of a pose) instead of estimating it from the fit's residuals."""

    name: str
    rows: np.ndarray
    dof_per_row: np.ndarray
    floor: float
    start: float
    fixed: bool = False


@dataclass(frozen=True)
class RegularisedFit:
    """theta (p,), se (p,) posterior standard errors, held (p,) bool (held by the prior), cov (p, p),
    sigma {group: noise}, sigma_estimated {group: bool} (False: the floor, too few dof), determined
    (the number of parameter combinations the data determine), info_share {group: (p,)} the share of
    each parameter's data information from each group, residual (m,) raw (unwhitened), names."""

    theta: np.ndarray
    se: np.ndarray
    held: np.ndarray
    cov: np.ndarray
    sigma: dict
    sigma_estimated: dict
    determined: int
    info_share: dict
    residual: np.ndarray
    names: list


def _whiten(groups: list[Group], sigma: dict, m: int) -> np.ndarray:
    """(m,) factor 1/σ_g of every residual row."""
    scale = np.zeros(m)
    for g in groups:
        scale[g.rows] = 1.0 / sigma[g.name]
    return scale


def _cost(r: np.ndarray, theta: np.ndarray, theta0: np.ndarray, q: np.ndarray) -> float:
    """‖r‖² + (θ − θ0)ᵀ Q (θ − θ0)."""
    d = theta - theta0
    return float(r @ r + d @ q @ d)


def _solve(fun, theta: np.ndarray, theta0: np.ndarray, q: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Levenberg-Marquardt minimum of ‖scale ⊙ r(θ)‖² + (θ − θ0)ᵀ Q (θ − θ0) from θ."""
    r, jac = fun(theta)
    r, jac = r * scale, jac * scale[:, None]
    cost, mu = _cost(r, theta, theta0, q), 1e-3
    for _ in range(LM_ITERATIONS):
        a = jac.T @ jac + q
        grad = jac.T @ r + q @ (theta - theta0)
        damping = mu * np.maximum(np.diag(a), 1e-12)
        step = np.linalg.solve(a + np.diag(damping), -grad)
        trial = theta + step
        r_t, jac_t = fun(trial)
        r_t, jac_t = r_t * scale, jac_t * scale[:, None]
        cost_t = _cost(r_t, trial, theta0, q)
        if cost_t <= cost:
            done = cost - cost_t <= LM_TOLERANCE * max(cost, 1e-300)
            theta, r, jac, cost, mu = trial, r_t, jac_t, cost_t, max(mu / 3.0, 1e-12)
            if done:
                break
        else:
            mu *= 4.0
            if mu > 1e12:
                break
    return theta


def _weak_projector(h: np.ndarray) -> tuple[np.ndarray, int]:
    """(projector on the eigen-directions of the whitened information h with λ < DETERMINED_INFO,
    number of determined directions)."""
    lam, vec = np.linalg.eigh(0.5 * (h + h.T))
    weak = vec[:, lam < DETERMINED_INFO]
    return weak @ weak.T, int(np.sum(lam >= DETERMINED_INFO))


def _group_sigma(groups: list[Group], r: np.ndarray, leverage: np.ndarray) -> tuple[dict, dict]:
    """({group: σ}, {group: estimated?}) from raw residuals r (m,) and row leverages (m,): σ² = Σ r² over
    the group's rows / (its dof − its leverage)."""
    sigma, estimated = {}, {}
    for g in groups:
        dof = float(np.sum(g.dof_per_row)) - float(np.sum(leverage[g.rows]))
        if dof >= MIN_GROUP_DOF and not g.fixed:
            value = np.sqrt(float(np.sum(r[g.rows] ** 2)) / dof)
            sigma[g.name], estimated[g.name] = max(value, g.floor), True
        else:
            sigma[g.name], estimated[g.name] = max(g.start, g.floor), False
    return sigma, estimated


def regularised_fit(fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], theta0: np.ndarray,
                    prior_sigma: np.ndarray, names: list[str], groups: list[Group],
                    start: np.ndarray | None = None) -> RegularisedFit:
    """Fit θ (p,) to the residuals fun(θ) -> (r (m,), dr/dθ (m, p)) in the residuals' own units, grouped
    by `groups` (every row in exactly one group), under the prior θ0 (p,) ± prior_sigma (p,) (see the
    module docstring). start: first iterate (θ0 when None)."""
    theta0 = np.asarray(theta0, dtype=float)
    s = np.asarray(prior_sigma, dtype=float)
    theta = theta0.copy() if start is None else np.asarray(start, dtype=float).copy()
    m = len(fun(theta)[0])
    sigma = {g.name: max(g.start, g.floor) for g in groups}
    estimated = {g.name: False for g in groups}
    q = np.diag(1.0 / s ** 2)                       # the full prior first: a safe start
    for _ in range(OUTER_ITERATIONS):
        theta = _solve(fun, theta, theta0, q, _whiten(groups, sigma, m))
        r, jac = fun(theta)
        jw = jac * _whiten(groups, sigma, m)[:, None]
        h = (jw * s).T @ (jw * s)
        projector, determined = _weak_projector(h)
        inv = np.linalg.inv(h + projector)
        leverage = np.einsum("ij,jk,ik->i", jw * s, inv, jw * s)
        new_sigma, estimated = _group_sigma(groups, r, leverage)
        q_new = (projector / s[:, None]) / s[None, :]
        stable = all(abs(new_sigma[k] - sigma[k]) <= 1e-3 * sigma[k] for k in sigma) and np.allclose(q_new, q)
        sigma, q = new_sigma, q_new
        if stable:
            break
    theta = _solve(fun, theta, theta0, q, _whiten(groups, sigma, m))
    r, jac = fun(theta)
    jw = jac * _whiten(groups, sigma, m)[:, None]
    h = (jw * s).T @ (jw * s)
    projector, determined = _weak_projector(h)
    cov = (np.linalg.inv(h + projector) * s[:, None]) * s[None, :]
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return RegularisedFit(theta, se, se > HELD_SHARE * s, cov, sigma, estimated, determined,
                          _info_share(groups, jw), r, list(names))


def _info_share(groups: list[Group], jw: np.ndarray) -> dict:
    """{group: (p,)} share of each parameter's data information (diagonal of JᵀJ) from each group."""
    per = {g.name: np.sum(jw[g.rows] ** 2, axis=0) for g in groups}
    total = np.maximum(sum(per.values()), 1e-300)
    return {k: v / total for k, v in per.items()}


def parameter_label(name: str) -> str:
    """A reader's name of a model parameter: A[i,i] -> 'gain x', A[i,j] -> 'cross-axis xy' (row i, column
    j), 'bx·Tn^0' -> 'bias x', 'bx·Tn^k' -> 'bias x·Tn^k', 'gx·Tn^k' -> 'gain x·Tn^k'; others unchanged."""
    axes = "xyz"
    if name.startswith("A[") and name.endswith("]"):
        i, j = (int(v) for v in name[2:-1].split(","))
        return f"gain {axes[i]}" if i == j else f"cross-axis {axes[i]}{axes[j]}"
    if name[:1] in "bg" and "·Tn^" in name:
        what = {"b": "bias", "g": "gain"}[name[0]]
        axis, power = name[1], name.split("^")[1]
        return f"{what} {axis}" if power == "0" else f"{what} {axis}·Tn^{power}"
    return name


def propagated_se(derived: Callable[[np.ndarray], dict], theta: np.ndarray, cov: np.ndarray,
                  step: float = 1e-7) -> dict:
    """{key: standard errors} of the quantities derived(θ) -> {key: array} by linear propagation of the
    covariance cov (p, p) (central differences with `step` on each parameter)."""
    base = derived(theta)
    jac = {k: np.zeros((np.size(v), len(theta))) for k, v in base.items()}
    for i in range(len(theta)):
        d = np.zeros(len(theta))
        d[i] = step
        up, down = derived(theta + d), derived(theta - d)
        for k in base:
            jac[k][:, i] = (np.ravel(up[k]) - np.ravel(down[k])) / (2 * step)
    return {k: np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", j, cov, j), 0.0)) for k, j in jac.items()}


def uncertainty_report(fit: RegularisedFit, derived: Callable[[np.ndarray], dict], n_model: int) -> dict:
    """Report entries of a regularised fit: every model parameter (the first n_model of θ; the rest are
    nuisances) with value, standard error, whether the prior held it and the residual group that
    informed it most; the names held; the standard errors of the derived quantities ('<key>_se'); the
    noise of each residual group and whether it was estimated from the residuals or is the floor."""
    params = []
    for i in range(n_model):
        share = {g: float(v[i]) for g, v in fit.info_share.items()}
        source = max(share, key=share.get) if any(share.values()) else None
        params.append({"name": fit.names[i], "label": parameter_label(fit.names[i]),
                       "value": float(fit.theta[i]), "se": float(fit.se[i]), "held": bool(fit.held[i]),
                       "from": source})
    out = {"parameters": params, "held": [p["label"] for p in params if p["held"]],
           "determined_combinations": fit.determined,
           "residual_noise": {g: {"sigma": float(v), "estimated": bool(fit.sigma_estimated[g])}
                              for g, v in fit.sigma.items()}}
    for key, se in propagated_se(derived, fit.theta, fit.cov).items():
        out[f"{key}_se"] = se
    return out
