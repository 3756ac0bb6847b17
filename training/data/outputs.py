"""What a verb may do to the files it writes (issue 31, "outputs are never lost or mixed"):

- it never writes over one of its own inputs (`refuse_overwriting_inputs`: `diagnose --model
  m/model.json --out m` replaced the model it read);
- a run that writes a set of units (`fleet train`, `simulate-fleet`) first removes what describes the
  previous run (its summary files) and the units that run listed and this one will not write
  (`forget_previous_run`): a run stopped half-way leaves no summary that speaks for units it did
  not write, and a finished one leaves no unit of an earlier run beside its own;
- a unit is written into a temporary folder beside its place and moved there only when complete
  (`replace_folder`); a unit that fails leaves no model of an earlier run in its place;
- every verb of the CLI writes its output through `staged_output`: into a temporary folder beside the
  target, moved into place only when the verb completes (a failure or an interruption leaves the
  previous output as it was); an existing output is kept unless `--force`, and even then a folder is
  replaced only when it is empty or an earlier imufmu output (it holds MARKER), never a folder of the
  user's own files.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from contract.errors import ImuFusionError


class OutputError(ImuFusionError):
    """An output would destroy an input."""


#: The file a folder output of the CLI carries (the verb that wrote it): `--force` replaces such a
#: folder, never one without it (unless empty).
MARKER = ".imufmu-output"
#: How a verb writes: FOLDER owns its --out folder (replaced as a whole); FILE writes the file --out names
#: (and companions beside it, e.g. a sidecar); INTO adds files to the --out folder (a simulated
#: recording). FILE and INTO outputs are moved into place file by file.
FOLDER, FILE, INTO = "folder", "file", "into"


def refuse_overwriting_inputs(verb: str, inputs: Iterable[str | Path], outputs: Iterable[str | Path],
                              folder: bool = False) -> None:
    """OutputError naming the file when one of `outputs` is one of `inputs` (after resolving links), or,
    with `folder` (the outputs are folders a verb replaces as a whole), when an input lies inside one."""
    read = {Path(p).resolve(): Path(p) for p in inputs}
    for out in outputs:
        where = Path(out).resolve()
        hit = read.get(where) or next((p for r, p in read.items() if folder and where in r.parents), None)
        if hit is not None:
            raise OutputError(f"{hit}: imufmu {verb} would write over this input (its output {out}); "
                              "choose another --out")


@dataclass(frozen=True)
class StagedOutput:
    """Where a verb writes while it runs (`path`) and where that goes when it completes (`target`)."""

    target: Path
    staging: Path
    kind: str

    @property
    def path(self) -> Path:
        """The path to give the verb: the staging folder (FOLDER, INTO) or the target's name in it (FILE)."""
        return self.staging / self.target.name if self.kind == FILE else self.staging

    @property
    def destination(self) -> Path:
        """The folder the staged files go to (the target itself for FOLDER and INTO)."""
        return self.target.parent if self.kind == FILE else self.target

    def final(self, path: str | Path) -> Path:
        """Where `path` (inside the staging folder) will be once the output is in place."""
        return self.destination / Path(path).relative_to(self.staging)


def _refuse_existing(verb: str, target: Path, force: bool, kind: str, names: Iterable[str]) -> None:
    """OutputError when the output would replace something it may not: without `force` any existing
    output; with it a folder that holds neither nothing nor MARKER, or a file where a folder goes (and
    the reverse). names: the files a FILE or INTO output writes (beside the target, or in it)."""
    if kind == FOLDER:
        if target.is_file():
            raise OutputError(f"{target}: is a file; imufmu {verb} writes a folder here; choose another --out")
        if target.is_dir() and any(target.iterdir()):
            if not force:
                raise OutputError(f"{target}: exists and is not empty; imufmu {verb} keeps an existing output — "
                                  "pass --force to replace it (the new one is moved into place only when complete)")
            if not (target / MARKER).is_file():
                raise OutputError(f"{target}: holds files imufmu did not write (no {MARKER}); --force replaces only "
                                  f"an earlier imufmu output; choose an empty or new folder")
        return
    if kind == INTO and target.is_file():
        raise OutputError(f"{target}: is a file; imufmu {verb} writes into a folder here; choose another --out")
    for name in names:
        path = target / name if kind == INTO else target.with_name(name)
        if path.is_dir():
            raise OutputError(f"{path}: is a folder; imufmu {verb} writes a file here; choose another --out")
        if path.exists() and not force:
            raise OutputError(f"{path}: exists; imufmu {verb} keeps an existing output — pass --force to replace it "
                              "(the new one is moved into place only when complete)")


@contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM held back (delivered after the block): the moves into place are not cut short."""
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _move_into_place(verb: str, out: StagedOutput, force: bool) -> None:
    """The staged output moved to its target: FOLDER swapped in whole (MARKER written first), FILE and INTO
    file by file into their folder (each refused when it exists without `force`)."""
    if out.kind == FOLDER:
        (out.staging / MARKER).write_text(json.dumps({"verb": verb}) + "\n")
        _swap_folder(out.staging, out.target)
        return
    written = sorted(p.name for p in out.staging.iterdir())
    _refuse_existing(verb, out.target, force, out.kind, written)
    with _signals_held():
        for name in written:
            os.replace(out.staging / name, out.destination / name)


def _staging_folder(target: Path) -> Path:
    """An empty hidden folder beside `target` (.NAME.partial-PID) to write it in."""
    staging = target.with_name(f".{target.name}.partial-{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    return staging


def _swap_folder(staging: Path, target: Path) -> None:
    """The complete folder `staging` in the place of `target` (the earlier one removed), the two renames
    not cut short by a signal."""
    old = target.with_name(f".{target.name}.old-{os.getpid()}")
    with _signals_held():
        if target.exists():
            os.replace(target, old)
        os.replace(staging, target)
    shutil.rmtree(old, ignore_errors=True)


@contextmanager
def staged_output(verb: str, target: str | Path, force: bool, kind: str = FOLDER,
                  inputs: Iterable[str | Path] = (), names: Iterable[str] = ()) -> Iterator[StagedOutput]:
    """The output of `imufmu <verb> --out target`, written in a folder beside the target and moved into
    place when the block completes; when the block raises (a failure, Ctrl-C), the staging folder is
    removed and the previous output stays as it was.

    kind: FOLDER, FILE or INTO; inputs: the verb's input files (refused inside a FOLDER target, or as one
    of the files a FILE or INTO output writes); names: the other files a FILE output writes beside its
    target (a sidecar), or the files an INTO output will write in its folder, refused up front when they
    exist without `force` (and any other file it wrote when it is moved)."""
    target = Path(target)
    names = (target.name, *names) if kind == FILE else tuple(names)
    if kind == FOLDER:
        refuse_overwriting_inputs(verb, inputs, [target], folder=True)
    else:
        refuse_overwriting_inputs(verb, inputs, [target / n if kind == INTO else target.with_name(n) for n in names])
    _refuse_existing(verb, target, force, kind, names)
    staging = _staging_folder(target / target.name if kind == INTO else target)
    out = StagedOutput(target, staging, kind)
    try:
        yield out
        _move_into_place(verb, out, force)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


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
    staging = _staging_folder(target)
    try:
        result = write(staging)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        shutil.rmtree(target, ignore_errors=True)
        raise
    _swap_folder(staging, target)
    return result
