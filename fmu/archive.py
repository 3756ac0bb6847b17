"""Checked access to an FMU archive: what a malformed or hostile .fmu fails before anything is
loaded or extracted, and extraction that stops at the size caps.

An FMU is a zip archive with modelDescription.xml at the top and the binary of this platform
under binaries/. Every problem is one FmuArchiveError line naming the file and the problem: not a
zip, empty, a member name that would land outside the extraction folder (absolute, '..', a drive
letter or a backslash), more than MAX_MEMBERS members, a member whose declared or actual size
exceeds MAX_MEMBER_BYTES (or all together MAX_TOTAL_BYTES), no or a malformed
modelDescription.xml (an FMU zipped inside another zip is named as such), a modelIdentifier that
is not a plain C name (it is joined into the binary's path, so '../../tmp/x/evil' would load a
library from outside the FMU), no binary. extracted_binary gives the binary to load only when it
resolves to a file inside the extraction folder.
"""
from __future__ import annotations

import re
import zipfile
import zlib
from pathlib import Path, PurePosixPath

import fmpy

from fmu.compiler import binary_path
from contract.errors import ImuFusionError, one_line

#: Caps on what an archive may cost: the ImuFusion FMU holds 45 members (FMI 3: 46), 0.75 MB unpacked.
MAX_MEMBERS = 10_000
MAX_MEMBER_BYTES = 64 * 2**20      # 64 MiB, declared or actual size of one member
MAX_TOTAL_BYTES = 256 * 2**20      # 256 MiB, all members together
COPY_CHUNK_BYTES = 2**20           # extraction streams members in chunks of this size
MODEL_DESCRIPTION = "modelDescription.xml"
_DRIVE = re.compile(r"^[A-Za-z]:")
#: What the FMI standard allows as modelIdentifier: a C name (letters, digits, underscore), which
#: is also the binary's file name without extension.
_C_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


class FmuArchiveError(ImuFusionError):
    """The file is not a usable FMU archive; the message names the file and the problem."""

    def __init__(self, path, problem: str):
        super().__init__(f"{path}: {problem}")


def _unsafe_name_problem(name: str) -> str | None:
    """Why member `name` may not be extracted (it would land outside the folder), or None."""
    if "\\" in name:
        return f"member name {name!r} contains a backslash"
    if name.startswith("/") or _DRIVE.match(name):
        return f"member name {name!r} is an absolute path"
    if ".." in PurePosixPath(name).parts:
        return f"member name {name!r} contains '..'"
    return None


def check_archive(path: str | Path) -> list[zipfile.ZipInfo]:
    """The members of the FMU archive at path after the archive checks (names, counts, declared
    sizes, modelDescription.xml at the top); FmuArchiveError otherwise."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as zf:
            members = zf.infolist()
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError):
        raise FmuArchiveError(path, "not an FMU (an FMU is a zip archive; this file is not one)") from None
    if not members:
        raise FmuArchiveError(path, "the FMU archive is empty")
    if len(members) > MAX_MEMBERS:
        raise FmuArchiveError(path, f"the archive has {len(members)} members, more than {MAX_MEMBERS}")
    for info in members:
        problem = _unsafe_name_problem(info.filename)
        if problem:
            raise FmuArchiveError(path, f"{problem}; refused (it would be extracted outside the FMU folder)")
        if info.file_size > MAX_MEMBER_BYTES:
            raise FmuArchiveError(path, f"member {info.filename!r} declares {info.file_size} bytes, "
                                        f"more than the {MAX_MEMBER_BYTES // 2**20} MiB cap")
    total = sum(info.file_size for info in members)
    if total > MAX_TOTAL_BYTES:
        raise FmuArchiveError(path, f"the members declare {total} bytes, more than the "
                                    f"{MAX_TOTAL_BYTES // 2**20} MiB cap")
    names = {info.filename for info in members}
    if MODEL_DESCRIPTION not in names:
        nested = sorted(n for n in names if n.lower().endswith((".fmu", ".zip")))
        hint = f"; it holds {nested[0]!r}: give that FMU itself, not a zip of it" if nested else ""
        raise FmuArchiveError(path, f"no {MODEL_DESCRIPTION} at the top of the archive{hint}")
    return members


def _copy_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, target: Path, path: Path) -> int:
    """Stream one member to target, refusing it once it exceeds MAX_MEMBER_BYTES; returns its size."""
    size = 0
    with zf.open(info) as source, open(target, "wb") as sink:
        while chunk := source.read(COPY_CHUNK_BYTES):
            size += len(chunk)
            if size > MAX_MEMBER_BYTES:
                raise FmuArchiveError(path, f"member {info.filename!r} inflates beyond the "
                                            f"{MAX_MEMBER_BYTES // 2**20} MiB cap")
            sink.write(chunk)
    return size


def extract_archive(path: str | Path, unzipdir: str | Path) -> Path:
    """Extract the checked FMU archive at path into unzipdir, member by member within the caps;
    FmuArchiveError for a malformed archive or a member that is corrupt or larger than it declares."""
    path, unzipdir = Path(path), Path(unzipdir)
    members = check_archive(path)
    total = 0
    try:
        with zipfile.ZipFile(path) as zf:
            for info in members:
                target = unzipdir / info.filename
                if info.is_dir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                total += _copy_member(zf, info, target, path)
                if total > MAX_TOTAL_BYTES:
                    raise FmuArchiveError(path, f"the members inflate beyond the {MAX_TOTAL_BYTES // 2**20} MiB cap")
    except (zipfile.BadZipFile, zlib.error, EOFError, ValueError, NotImplementedError) as e:
        raise FmuArchiveError(path, f"a member is corrupt ({one_line(str(e))})") from None
    return unzipdir


def read_description(path: str | Path, unzipdir: str | Path | None = None) -> fmpy.model_description.ModelDescription:
    """The model description of the FMU at path (read from unzipdir when already extracted there),
    checked to name a co-simulation model whose binary for this platform is present; FmuArchiveError
    otherwise."""
    path = Path(path)
    if unzipdir is None:
        check_archive(path)
    try:
        description = fmpy.read_model_description(str(unzipdir or path))
    except Exception as e:  # fmpy raises bare Exception, lxml XMLSyntaxError, KeyError, ...
        raise FmuArchiveError(path, f"{MODEL_DESCRIPTION} is malformed ({one_line(str(e)) or type(e).__name__})") from None
    if description.coSimulation is None:
        raise FmuArchiveError(path, "the FMU does not support co-simulation")
    identifier = description.coSimulation.modelIdentifier
    if not isinstance(identifier, str) or not _C_NAME.fullmatch(identifier):
        raise FmuArchiveError(path, f"modelIdentifier {identifier!r} is not a plain C name (letters, digits, "
                                    "underscore); refused (it names the binary to load)")
    member = _binary_member(description)
    present = _inside_file(Path(unzipdir), member) is not None if unzipdir is not None else _has_member(path, member)
    if not present:
        raise FmuArchiveError(path, f"no binary {member} for this platform in the FMU")
    return description


def extracted_binary(path: str | Path, unzipdir: str | Path,
                     description: fmpy.model_description.ModelDescription) -> Path:
    """The absolute path of the FMU's binary for this platform in the folder unzipdir where the FMU
    at path was extracted, checked to resolve (symbolic links followed) to a file inside unzipdir;
    FmuArchiveError otherwise. Load nothing else."""
    member = _binary_member(description)
    binary = _inside_file(Path(unzipdir), member)
    if binary is None:
        raise FmuArchiveError(path, f"no binary {member} inside the extracted FMU; refused to load it")
    return binary


def _binary_member(description: fmpy.model_description.ModelDescription) -> str:
    """The archive member name of this platform's co-simulation binary the description names."""
    version = 3 if description.fmiVersion.startswith("3") else 2
    return binary_path(Path(), description.coSimulation.modelIdentifier, version).as_posix()


def _inside_file(unzipdir: Path, member: str) -> Path | None:
    """unzipdir/member resolved, when that is an existing file inside unzipdir; else None."""
    root = unzipdir.resolve()
    target = (root / member).resolve()
    return target if target.is_relative_to(root) and target.is_file() else None


def _has_member(path: Path, member: str) -> bool:
    """True when the (checked) archive at path has the member."""
    with zipfile.ZipFile(path) as zf:
        return member in zf.namelist()



def declared_mounting(path: str | Path) -> tuple[int, int, int]:
    """The mounting the FMU at path declares: the start values of mount_x, mount_y, mount_z in its
    model description (contract.mounting; the FMU reports in the body axes they define)."""
    from contract.mounting import MOUNT_SETTINGS
    starts = {v.name: v.start for v in read_description(path).modelVariables if v.name in MOUNT_SETTINGS}
    return tuple(int(float(starts[name])) for name in MOUNT_SETTINGS)
