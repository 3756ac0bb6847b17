"""What a verb may do to the files it writes (issue 31, "outputs are never lost or mixed"):

- it never writes over one of its own inputs (`refuse_overwriting_inputs`: `diagnose --model
  m/model.json --out m` replaced the model it read);
- a run that writes a set of units (`fleet train`, `simulate-fleet`) first removes what describes the
  previous run (its summary files) and the units that run listed and this one will not write
  (`forget_previous_run`): a run stopped half-way leaves no summary that speaks for units it did
  not write, and a finished one leaves no unit of an earlier run beside its own;
- a unit is written into a temporary folder beside its place and moved there only when complete
  (`replace_folder`); a unit that fails leaves no model of an earlier run in its place.
"""
from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterable
from pathlib import Path

from contract.errors import ImuFusionError


class OutputError(ImuFusionError):
    """An output would destroy an input."""


def refuse_overwriting_inputs(verb: str, inputs: Iterable[str | Path], outputs: Iterable[str | Path]) -> None:
    """OutputError naming the file when one of `outputs` is one of `inputs` (after resolving links)."""
    read = {Path(p).resolve(): Path(p) for p in inputs}
    for out in outputs:
        hit = read.get(Path(out).resolve())
        if hit is not None:
            raise OutputError(f"{hit}: imufmu {verb} would write over this input (its output {out}); "
                              "choose another --out")


def forget_previous_run(out_dir: Path, summaries: Iterable[str], listed: str, keeping: Iterable[str]) -> list[str]:
    """Before a run that writes units into out_dir: read the unit names the previous run listed in the
    JSON file `listed` (a list of names, or of {'unit': name}), remove those not in `keeping` (their
    folders) and the previous run's summary files; returns the units removed."""
    previous = _listed_units(out_dir / listed)
    keep = set(keeping)
    removed = [u for u in previous if u not in keep and (out_dir / u).is_dir() and Path(u).name == u]
    for unit in removed:
        shutil.rmtree(out_dir / unit)
    for name in summaries:
        (out_dir / name).unlink(missing_ok=True)
    return removed


def _listed_units(path: Path) -> list[str]:
    """Unit names in a run's JSON listing (none when it is missing or unreadable)."""
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        return []
    entries = doc.get("units", []) if isinstance(doc, dict) else doc
    names = [e.get("unit") if isinstance(e, dict) else e for e in entries if isinstance(e, (dict, str))]
    return [n for n in names if isinstance(n, str) and n]


def replace_folder(target: Path, write) -> object:
    """Call write(temporary folder) and move the folder to `target` when it returns (replacing what
    was there); when it raises, the temporary folder and any earlier `target` are removed (no output
    of an earlier run stays in the place of one that failed) and the exception propagates."""
    target = Path(target)
    staging = target.with_name(f".{target.name}.partial-{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    try:
        result = write(staging)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        shutil.rmtree(target, ignore_errors=True)
        raise
    old = target.with_name(f".{target.name}.old-{os.getpid()}")
    if target.exists():
        os.replace(target, old)
    os.replace(staging, target)
    shutil.rmtree(old, ignore_errors=True)
    return result
