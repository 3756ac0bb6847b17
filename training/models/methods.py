"""The four source methods as a user selects them (issue 33): `imufmu train --method NAME=FORM`.

Each method runs either as its source describes it or in the product's form; a selection is recorded in
model.json (`methods`) and reaches the FMU through its parameters (the runtime forms: euler_additions,
pf_additions, pf_rao_blackwell, psobp_clamp, …) and through how `train` fits the coefficients the FMU
carries (the training forms: the ELM's schedule, the PSO-BP fit's switches). A selected stage is switched on
whatever the held-out check says (the user asked to run it); the check stays in the notes. Without a
selection `train` chooses as before. Every deviation of the product's forms from the sources: docs/elm.md,
docs/magpf.md, docs/thermal_models.md and docs/euler.md ("As written / as built").
"""
from __future__ import annotations

from dataclasses import dataclass, field

from contract.ranges import EULER_ALL_ADDITIONS


@dataclass(frozen=True)
class Form:
    """One form of a method: what it is (one line), the FMU settings it sets and its training options."""

    text: str
    settings: dict[str, float]
    fit: dict = field(default_factory=dict)


#: The methods whose coefficients `train` fits (the others run online in the FMU only).
FITTED = ("elm", "psobp")
#: method -> form -> Form. The first form of each is the source's; a fitted method's form without training
#: options is fitted by its fitter's defaults (ElmFitter, PsoBpFitter: the product's).
METHODS: dict[str, dict[str, Form]] = {
    "elm": {
        "source": Form("the extreme learning machine with self back-tuning as its source fits it (growth, then plain "
                       "gradient-descent back-tuning)", {"enable_elm": 1.0}, {"schedule": "source"}),
        "product": Form("the ELM with the product's Adam back-tuning schedule", {"enable_elm": 1.0}),
    },
    "pf": {
        "source": Form("the particle filter with double-threshold splitting and the BP diversity network as its "
                       "source describes it: 9 states, every measurement, no project addition",
                       {"enable_pf": 1.0, "pf_rao_blackwell": 0.0, "pf_additions": 0.0, "pf_decimation": 1.0,
                        "pf_sphere_bins": 0.0, "pf_min_rotation": 0.0}),
        "stabilised": Form("the 9-state method with the project's additions (roughening, resample-move, tempering, "
                           "inflation, change test, glitch clipping, direction buffer, rotation gate)",
                           {"enable_pf": 1.0, "pf_rao_blackwell": 0.0, "pf_additions": 1.0}),
        "rb": Form("the product's Rao-Blackwellised filter (hard iron sampled, soft iron integrated out)",
                   {"enable_pf": 1.0, "pf_rao_blackwell": 1.0, "pf_additions": 1.0}),
    },
    "psobp": {
        "source": Form("the PSO-BP gyro bias network as its source fits and evaluates it (single-sample targets, "
                       "plain swarm, gradient descent, no input clamp)", {"enable_psobp": 1.0, "psobp_clamp": 0.0},
                       {"window_s": None, "pso_clamp": False, "ls_threshold": False, "bp_rule": "gd",
                        "early_stop": False}),
        "product": Form("the PSO-BP network in the product's form (window-mean targets, clamped swarm, "
                        "least-squares threshold, Rprop, early stop, inputs clamped)",
                        {"enable_psobp": 1.0, "psobp_clamp": 1.0}),
    },
    "attitude": {
        "source-euler": Form("the adaptive-gain Euler fusion as its source describes it (no project addition)",
                             {"attitude_mode": 0.0, "euler_additions": 0.0}),
        "euler": Form("the adaptive-gain Euler fusion with the project's additions",
                      {"attitude_mode": 0.0, "euler_additions": float(EULER_ALL_ADDITIONS)}),
        "quaternion": Form("the product's quaternion filter with gyro bias at rest and disturbance rejection",
                           {"attitude_mode": 1.0}),
    },
}


def parse_method(text: str) -> tuple[str, str]:
    """(method, form) of a `--method NAME=FORM` argument; ValueError naming the choices otherwise."""
    name, _, form = text.partition("=")
    if name not in METHODS:
        raise ValueError(f"--method {text!r}: unknown method {name!r} (choose {', '.join(METHODS)})")
    if form not in METHODS[name]:
        raise ValueError(f"--method {text!r}: {name} has the forms {', '.join(METHODS[name])}")
    return name, form


def fit_options(methods: dict[str, str], method: str) -> dict:
    """The training options of the selected form of `method` (empty when none is selected)."""
    return dict(METHODS[method][methods[method]].fit) if method in methods else {}


def method_settings(methods: dict[str, str]) -> dict[str, float]:
    """The FMU settings of every selected form."""
    return {k: v for method, form in methods.items() for k, v in METHODS[method][form].settings.items()}


def method_notes(methods: dict[str, str], chosen: dict[str, float]) -> list[str]:
    """One note per selection: the form, and train's own choice where the selection overrode it (`chosen`:
    the settings train wrote before the selection applied)."""
    notes = []
    for method, form in methods.items():
        changed = {k: v for k, v in METHODS[method][form].settings.items() if chosen.get(k) != v}
        overridden = ", ".join(f"{k} = {chosen[k]:g}" for k in changed if k in chosen)
        notes.append(f"method: {method} = {form} (--method): {METHODS[method][form].text}"
                     + (f"; train's own choice was {overridden}" if overridden else ""))
    return notes


#: The header of `table`.
TABLE_HEADER = "| method | form | what runs | FMU parameters it sets | how `train` fits |"


def _fit_text(method: str, fit: dict) -> str:
    """A form's training options as text."""
    if method not in FITTED:
        return "— (runs online only)"
    return ", ".join(f"`{k} = {v!r}`" for k, v in fit.items()) or "the fitter's defaults (the product's)"


def table() -> str:
    """docs/methods.md's table of every method and form (the first form of each is the source's)."""
    rows = [TABLE_HEADER, "|---|---|---|---|---|"]
    for method, forms in METHODS.items():
        for name, form in forms.items():
            settings = ", ".join(f"`{k} = {v:g}`" for k, v in form.settings.items())
            rows.append(f"| `{method}` | `{name}` | {form.text} | {settings} | {_fit_text(method, form.fit)} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print("Command: `python -m training.models.methods`\n")
    print(table())
