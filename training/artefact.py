"""The trained-model artefact: versioned JSON (ARCHITECTURE.md, 'Training pipeline').

One file carries everything needed to regenerate the FMU coefficient header and to reproduce
the fit: format and version, model type, units, seed, library versions, training data, the
per-triad gain/bias temperature models with their fit statistics, the neural stages (ELM,
PSO-BP) as named parts in their units, recommended FMU settings and notes. Floats are written by
Python's shortest round-trip repr, so load(save(x)) is exact.

Format 2 stores the neural stages by name (`stages`); format 1 stored them as the runtime's raw
coefficient blocks (`blocks`). A format-1 file loads through `_upgrade_format_1`, which reads the
blocks with the stages' own block readers; it is written back as format 2.
"""
from __future__ import annotations

import json
import platform
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from contract.errors import ModelError
from contract.layout import (AUX_INPUTS, MAX_DEGREE, STAGE_BLOCKS, TERM_SIGNALS, TERM_TARGETS, TERMS_MAX,
                             TRIAD_ORDER, pack_coefficients, settings_defaults, terms_block)
from contract.mounting import mounting_problem, settings_codes
from contract.schema import setting_problem
from training.models.model_checks import flag_problem, term_problem, thermal_problem
from training.models.thermal import ThermalModel

if TYPE_CHECKING:  # the neural stages import torch: loaded when an artefact has or writes one
    from training.models.elm import ElmModel
    from training.models.psobp import PsoBpModel

FORMAT = "imufusion-model"
FORMAT_VERSION = 2
#: Older format versions that still load (through a converter).
UPGRADABLE = {1}
MODEL_TYPE = "imufusion-chain"
UNITS = {"t": "s", "gyr": "rad/s", "acc": "m/s²", "mag": "µT", "temp": "°C",
         "declination": "rad", "field_norm": "µT", "gyro_noise": "rad/s/√Hz",
         "gyro_bias_residual": "rad/s"}
_TOP_KEYS = ("format", "format_version", "model_type", "created", "seed", "units", "libraries",
             "training_data", "thermal", "fit_stats", "settings", "notes")
_THERMAL_KEYS = ("enabled", "t0", "ts", "degree", "A", "g", "b")


def library_versions() -> dict[str, str]:
    """Versions of python, numpy, torch and our distribution (contract.version.DISTRIBUTION) in
    this process."""
    import torch
    from contract.version import DISTRIBUTION, package_version
    return {"python": platform.python_version(), "numpy": np.__version__,
            "torch": torch.__version__, DISTRIBUTION: package_version()}


def libraries_from_json(libraries: dict) -> dict:
    """The libraries of a model file, our version under DISTRIBUTION: files written before it
    recorded it under 'imufusion' (the name of x-io's Fusion package), renamed on load."""
    from contract.version import DISTRIBUTION
    return {DISTRIBUTION if name == "imufusion" else name: version for name, version in libraries.items()}


def utc_now() -> str:
    """Current UTC time, ISO 8601 to the second."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


#: The neural stage that follows a triad's calibration in the runtime: triad -> (ModelArtefact field, the
#: setting that switches it). A stage trained on calibration data carries what was in that data.
NEURAL_STAGES = {"mag": ("elm", "enable_elm"), "gyr": ("psobp", "enable_psobp")}


@dataclass
class ModelArtefact:
    """A trained ImuFusion model.

    thermal: triad ('gyr', 'acc', 'mag') -> ThermalModel. fit_stats: triad -> dict of fit
    statistics (JSON scalars). training_data: [{'name', 'samples'}]. settings: setting name ->
    recommended FMU parameter value (contract.layout.SETTINGS units). notes: warnings.
    elm, psobp: the neural stages (training.models.elm.ElmModel, field form; training.models.psobp.
    PsoBpModel), None when not trained; settings enable_elm / enable_psobp switch them.
    terms: additive correction terms added by `imufmu diagnose`, each {'name', 'target', 'a', 'b',
    'coefficient', 'lo', 'hi'} with target/a/b names from contract.layout.TERM_TARGETS / TERM_SIGNALS
    (b may be None) and finite bounds lo <= hi of the regressor a·b; the runtime subtracts
    coefficient·clamp(a·b, lo, hi) from the target component (sources/ImuTerms.h).
    aux_inputs: what the FMU inputs aux_1.. carry, entry k for aux_{k+1} (at most
    len(contract.layout.AUX_INPUTS)): {'column': recording column 'aux_…', 'unit': unit text or '',
    'meaning': free text}. A term on signal aux_k needs entry k.
    methods: the source-method forms selected by `train --method` (training.models.methods.METHODS:
    method -> form); empty when train chose every stage itself.
    noise: the noise characterisation of the calibration's still data (training.noise, format
    imufusion-noise/1; written as "noise" when present), None when not characterised.
    """

    seed: int
    thermal: dict[str, ThermalModel]
    settings: dict[str, float]
    training_data: list[dict] = field(default_factory=list)
    fit_stats: dict[str, dict] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    terms: list[dict] = field(default_factory=list)
    aux_inputs: list[dict] = field(default_factory=list)
    methods: dict[str, str] = field(default_factory=dict)
    elm: ElmModel | None = None
    psobp: PsoBpModel | None = None
    noise: dict | None = None
    units: dict[str, str] = field(default_factory=lambda: dict(UNITS))
    libraries: dict[str, str] = field(default_factory=library_versions)
    created: str = field(default_factory=utc_now)
    format: str = FORMAT
    format_version: int = FORMAT_VERSION
    model_type: str = MODEL_TYPE

    def to_json_dict(self) -> dict:
        """The JSON document as plain Python objects."""
        doc = {"format": self.format, "format_version": self.format_version,
               "model_type": self.model_type, "created": self.created, "seed": self.seed,
               "units": dict(self.units), "libraries": dict(self.libraries),
               "training_data": list(self.training_data),
               "thermal": {k: _thermal_to_json(self.thermal[k]) for k in TRIAD_ORDER},
               "fit_stats": dict(self.fit_stats), "settings": dict(self.settings),
               "notes": list(self.notes), "terms": [dict(t) for t in self.terms],
               "aux_inputs": [dict(a) for a in self.aux_inputs], "methods": dict(self.methods),
               "stages": self.stages_to_json()}
        if self.noise is not None:
            doc["noise"] = self.noise
        return doc

    def stages_to_json(self) -> dict:
        """The trained neural stages by name, each as its model stores itself."""
        from training.models import elm
        stages = {}
        if self.elm is not None:
            stages["elm"] = elm.to_json(self.elm)
        if self.psobp is not None:
            stages["psobp"] = self.psobp.to_json()
        return stages

    def stage_blocks(self) -> dict[str, list[float]]:
        """The runtime's coefficient block of every trained stage (contract.layout.STAGE_BLOCKS)."""
        from training.models import elm
        blocks = {}
        if self.elm is not None:
            blocks["elm"] = [float(v) for v in elm.to_block(self.elm)]
        if self.psobp is not None:
            blocks["psobp"] = self.psobp.to_block()
        return blocks

    def to_json(self) -> str:
        """JSON text; NaN/inf are rejected (ValueError) rather than written non-standard."""
        return json.dumps(self.to_json_dict(), indent=2, ensure_ascii=False, allow_nan=False)

    def save(self, path) -> Path:
        """Write the artefact to `path` (UTF-8 JSON) and return the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.to_json() + "\n", encoding="utf-8")
        return path


def _thermal_to_json(model: ThermalModel) -> dict:
    """ThermalModel -> JSON object with nested lists (rows = axes); t_range [°C] is [t_min, t_max]
    or null (no range known)."""
    return {"enabled": model.enabled, "t0": model.t0, "ts": model.ts, "degree": model.degree,
            "A": model.A.tolist(), "g": model.g.tolist(), "b": model.b.tolist(),
            "t_range": None if model.t_range is None else list(model.t_range)}


def _t_range_from_json(doc: dict, where: str, path) -> tuple[float, float] | None:
    """The optional calibrated temperature range [t_min, t_max] [°C] of a thermal model; None when
    absent or null (an artefact from before layout version 4: no clamping)."""
    value = doc.get("t_range")
    if value is None:
        return None
    if not (isinstance(value, list) and len(value) == 2 and all(_is_number(v) for v in value)
            and value[0] <= value[1]):
        _fail(path, f"'{where}.t_range' is {value!r}, expected [t_min, t_max] in °C with t_min <= t_max")
    return float(value[0]), float(value[1])


def unranged_notes(thermal: dict[str, ThermalModel]) -> list[str]:
    """A note for each triad whose temperature polynomial has no calibrated range (no clamping)."""
    return [f"thermal.{triad}: no calibrated temperature range (an artefact from before layout version 4): "
            "the runtime evaluates its polynomial at any temperature without clamping; re-run imufmu train "
            "to record the range" for triad in TRIAD_ORDER
            if thermal[triad].enabled and thermal[triad].degree > 0 and thermal[triad].t_range is None]


def _fail(path, problem: str):
    """Raise the ModelError 'path: problem'."""
    raise ModelError(f"{path}: {problem}")


def _require(doc: dict, keys, where: str, path) -> None:
    """ModelError naming the first of `keys` missing from `doc`."""
    if not isinstance(doc, dict):
        _fail(path, f"'{where}' is not an object")
    for k in keys:
        if k not in doc:
            _fail(path, f"missing key '{where + '.' if where else ''}{k}'")


def _thermal_from_json(doc: dict, triad: str, path) -> ThermalModel:
    """JSON object -> ThermalModel; ModelError naming the triad and the bad entry."""
    where = f"thermal.{triad}"
    _require(doc, _THERMAL_KEYS, where, path)
    degree = doc["degree"]
    if not isinstance(degree, int) or isinstance(degree, bool) or not 0 <= degree <= MAX_DEGREE:
        _fail(path, f"'{where}.degree' is {degree!r}, expected an integer in 0..{MAX_DEGREE}")
    for name, shape in (("A", (3, 3)), ("g", (3, degree)), ("b", (3, degree + 1))):
        _check_shape(doc[name], shape, f"{where}.{name}", path)
    if flag_problem(doc["enabled"]):
        _fail(path, f"'{where}.enabled' {flag_problem(doc['enabled'])}")
    try:
        model = ThermalModel(bool(doc["enabled"]), doc["t0"], doc["ts"], degree,
                             np.array(doc["A"], dtype=float), np.array(doc["g"], dtype=float),
                             np.array(doc["b"], dtype=float), _t_range_from_json(doc, where, path))
    except (TypeError, ValueError) as exc:
        _fail(path, f"'{where}': {exc}")
    if thermal_problem(model, triad):
        _fail(path, thermal_problem(model, triad))
    return model


def _shape_text(value) -> str:
    """The shape of a JSON value for a message: '(3, 1)', 'ragged (rows of 3, 2, 3)' or a type name."""
    if not isinstance(value, list):
        return type(value).__name__
    try:
        return str(np.shape(value))
    except ValueError:  # a ragged list
        return "ragged (rows of " + ", ".join(str(len(r)) if isinstance(r, list) else type(r).__name__
                                              for r in value) + ")"


def _check_shape(value, shape: tuple[int, int], where: str, path) -> None:
    """ModelError unless `value` is a list of `shape[0]` numeric lists of length `shape[1]`."""
    rows_ok = isinstance(value, list) and len(value) == shape[0]
    if not rows_ok or not all(isinstance(r, list) and len(r) == shape[1] for r in value):
        _fail(path, f"'{where}' has shape {_shape_text(value)}, expected {shape}")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for r in value for v in r):
        _fail(path, f"'{where}' has non-numeric entries")


def _read_document(path) -> dict:
    """Parse the file as JSON; ModelError for a missing file or invalid JSON."""
    path = Path(path)
    if not path.is_file():
        _fail(path, "no such model file")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        _fail(path, f"not a JSON file ({exc})")
    if not isinstance(doc, dict):
        _fail(path, "not a model artefact (top level is not a JSON object)")
    return doc


def _check_header(doc: dict, path) -> None:
    """ModelError for a wrong format, format version or model type."""
    _require(doc, ("format", "format_version", "model_type"), "", path)
    if doc["format"] != FORMAT:
        _fail(path, f"format is {doc['format']!r}, expected {FORMAT!r}")
    if doc["format_version"] != FORMAT_VERSION and doc["format_version"] not in UPGRADABLE:
        _fail(path, f"format_version {doc['format_version']!r} is not supported "
                    f"(this version reads {', '.join(map(str, sorted({*UPGRADABLE, FORMAT_VERSION})))})")
    if doc["model_type"] != MODEL_TYPE:
        _fail(path, f"model_type is {doc['model_type']!r}, expected {MODEL_TYPE!r}")


def _settings_from_json(doc, path) -> dict[str, float]:
    """Settings object -> dict; ModelError for an unknown name or a value outside the setting's
    declared type and range (contract.layout.SETTING_RANGES; a Boolean may be true/false), and for
    mounting codes that are no rotation (training.mounting)."""
    if not isinstance(doc, dict):
        _fail(path, "'settings' is not an object")
    known = settings_defaults()
    for name, value in doc.items():
        if name not in known:
            _fail(path, f"unknown setting 'settings.{name}' (known: {', '.join(known)})")
        problem = setting_problem(name, value)
        if problem:
            _fail(path, f"settings: {problem}")
    problem = mounting_problem(settings_codes(doc))
    if problem:
        _fail(path, f"settings: {problem}")
    return {k: float(v) for k, v in doc.items()}


def _check_types(doc: dict, path) -> None:
    """ModelError for a top-level entry of the wrong JSON type."""
    expected = {"seed": int, "created": str, "units": dict, "libraries": dict,
                "training_data": list, "fit_stats": dict, "notes": list}
    for key, kind in expected.items():
        if not isinstance(doc[key], kind) or isinstance(doc[key], bool):
            _fail(path, f"'{key}' is {type(doc[key]).__name__}, expected {kind.__name__}")


def load_artefact(path) -> ModelArtefact:
    """Read a model artefact written by `ModelArtefact.save`.

    Raises ModelError naming the file and the problem: missing file, not JSON, wrong
    format/format_version/model_type, missing keys, wrong coefficient shapes. A thermal model
    without 't_range' (written before layout version 4) loads without a range: the runtime does
    not clamp its temperature, and the notes say so (`unranged_notes`).
    """
    doc = _read_document(path)
    _check_header(doc, path)
    if doc["format_version"] == 1:
        doc = _upgrade_format_1(doc, path)
    _require(doc, _TOP_KEYS, "", path)
    _require(doc["thermal"], TRIAD_ORDER, "thermal", path)
    thermal = {k: _thermal_from_json(doc["thermal"][k], k, path) for k in TRIAD_ORDER}
    _check_types(doc, path)
    return ModelArtefact(
        seed=doc["seed"], thermal=thermal, settings=_settings_from_json(doc["settings"], path),
        training_data=doc["training_data"], fit_stats=doc["fit_stats"],
        notes=doc["notes"] + [n for n in unranged_notes(thermal) if n not in doc["notes"]],
        terms=_terms_from_json(doc.get("terms", []), path),
        aux_inputs=_aux_inputs_from_json(doc.get("aux_inputs", []), doc.get("terms", []), path),
        methods=_methods_from_json(doc.get("methods", {}), path),
        **_stages_from_json(doc.get("stages", {}), path),
        noise=doc.get("noise") if isinstance(doc.get("noise"), dict) else None,
        units=doc["units"], libraries=libraries_from_json(doc["libraries"]), created=doc["created"],
        format=doc["format"], format_version=FORMAT_VERSION, model_type=doc["model_type"])


def _is_number(value) -> bool:
    """True for a finite JSON number (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and bool(np.isfinite(value))


def _terms_from_json(terms, path) -> list[dict]:
    """Validated correction terms (ModelError naming the file and the bad term)."""
    if not isinstance(terms, list) or len(terms) > TERMS_MAX:
        _fail(path, f"'terms' must be a list of at most {TERMS_MAX} terms")
    for k, term in enumerate(terms):
        ok = (isinstance(term, dict) and term.get("target") in TERM_TARGETS
              and term.get("a") in TERM_SIGNALS and (term.get("b") is None or term.get("b") in TERM_SIGNALS)
              and _is_number(term.get("coefficient")))
        if not ok:
            _fail(path, f"terms[{k}] must have target in {TERM_TARGETS}, a and b (or null) in "
                        f"TERM_SIGNALS and a finite coefficient")
        name = term.get("name", "unnamed")
        if "lo" not in term or "hi" not in term:
            _fail(path, f"terms[{k}] ({name}) has no regressor bounds 'lo' and 'hi' (an artefact from before "
                        f"layout version 3): re-run imufmu diagnose")
        if not (_is_number(term["lo"]) and _is_number(term["hi"]) and term["lo"] <= term["hi"]):
            _fail(path, f"terms[{k}] ({name}) needs finite regressor bounds lo <= hi, got lo = {term['lo']!r}, "
                        f"hi = {term['hi']!r}: re-run imufmu diagnose")
        if term_problem(term):
            _fail(path, f"terms[{k}] ({name}) {term_problem(term)}")
    return [dict(t) for t in terms]


def _methods_from_json(methods, path) -> dict[str, str]:
    """The 'methods' entry: method -> form, each a form of training.models.methods.METHODS."""
    from training.models.methods import METHODS
    if not isinstance(methods, dict) or any(not isinstance(f, str) or f not in METHODS.get(m, {})
                                            for m, f in methods.items()):
        _fail(path, "'methods' must map a method (" + ", ".join(METHODS) + ") to one of its forms")
    return dict(methods)


def _aux_inputs_from_json(aux_inputs, terms, path) -> list[dict]:
    """Validated auxiliary-input mapping (ModelError naming the file and the bad entry); `terms`
    (already validated) may use signal aux_k only when entry k exists."""
    if not isinstance(aux_inputs, list) or len(aux_inputs) > len(AUX_INPUTS):
        _fail(path, f"'aux_inputs' must be a list of at most {len(AUX_INPUTS)} entries")
    for k, entry in enumerate(aux_inputs):
        ok = (isinstance(entry, dict) and set(entry) == {"column", "unit", "meaning"}
              and isinstance(entry["column"], str) and entry["column"].startswith("aux_")
              and isinstance(entry["unit"], str) and isinstance(entry["meaning"], str))
        if not ok:
            _fail(path, f"aux_inputs[{k}] must be {{'column': 'aux_…', 'unit': text, 'meaning': text}}")
    columns = [a["column"] for a in aux_inputs]
    if len(set(columns)) != len(columns):
        _fail(path, f"aux_inputs maps a recording column twice ({', '.join(columns)})")
    for k, term in enumerate(terms):
        unmapped = [s for s in (term["a"], term.get("b")) if s in AUX_INPUTS[len(aux_inputs):]]
        if unmapped:
            _fail(path, f"terms[{k}] uses {unmapped[0]}, which aux_inputs does not map to a recording column")
    return [dict(a) for a in aux_inputs]


def _upgrade_format_1(doc: dict, path) -> dict:
    """A format-1 document as format 2: its raw stage `blocks` read by the stages' block readers
    (a disabled block is no stage)."""
    from training.models import elm
    from training.models.psobp import PsoBpModel
    blocks = doc.get("blocks", {})
    if not isinstance(blocks, dict):
        _fail(path, "'blocks' must be an object of stage name -> list of numbers")
    stages = {}
    for name, values in blocks.items():
        if name not in STAGE_BLOCKS:
            _fail(path, f"blocks: unknown stage '{name}' (known: {', '.join(STAGE_BLOCKS)})")
        if (not isinstance(values, list) or len(values) != STAGE_BLOCKS[name]
                or not all(isinstance(v, (int, float)) and np.isfinite(v) for v in values)):
            _fail(path, f"blocks.{name} must be {STAGE_BLOCKS[name]} finite numbers")
        try:
            model = elm.from_block(np.asarray(values)) if name == "elm" else PsoBpModel.from_block(values)
        except ValueError as e:
            _fail(path, f"blocks.{name}: {e}")
        if model is not None:
            stages[name] = elm.to_json(model) if name == "elm" else model.to_json()
    return {**{k: v for k, v in doc.items() if k != "blocks"}, "format_version": FORMAT_VERSION, "stages": stages}


def _stages_from_json(stages, path) -> dict:
    """{'elm': ElmModel, 'psobp': PsoBpModel} of the stages present; ModelError naming a bad one."""
    from training.models import elm
    from training.models.psobp import PsoBpModel
    if not isinstance(stages, dict):
        _fail(path, "'stages' must be an object of stage name -> model")
    readers = {"elm": elm.from_json, "psobp": PsoBpModel.from_json}
    models = {}
    for name, doc in stages.items():
        if name not in readers:
            _fail(path, f"stages: unknown stage '{name}' (known: {', '.join(readers)})")
        try:
            models[name] = readers[name](doc)
        except ValueError as e:
            _fail(path, f"stages.{name}: {e}")
    return models


def coefficients_array(artefact: ModelArtefact) -> np.ndarray:
    """The flat coefficient array of contract.layout, (N_COEFFICIENTS,) float64:
    [LAYOUT_VERSION, gyr, acc, mag thermal blocks, terms block, stage blocks]."""
    terms = terms_block([(t["target"], t["a"], t.get("b"), t["coefficient"], t["lo"], t["hi"])
                         for t in artefact.terms])
    blocks = [artefact.thermal[triad].to_block() for triad in TRIAD_ORDER]
    return np.array(pack_coefficients(blocks, terms, **artefact.stage_blocks()), dtype=np.float64)


def settings_dict(artefact: ModelArtefact) -> dict[str, float]:
    """Every setting in contract.layout.SETTINGS order: the artefact's value, else the default."""
    values = settings_defaults()
    values.update(artefact.settings)
    return values
