"""Read what a Windows DLL (PE/COFF image, Microsoft PE format specification) exports and imports:
the exported function names and the DLLs it loads, with the standard library only, so that
`imufmu validate` checks an FMU's win64 binary on a machine without mingw-w64 or Windows."""
from __future__ import annotations

import struct
from dataclasses import dataclass

#: IMAGE_FILE_MACHINE_AMD64: the COFF machine type of an x86-64 image.
MACHINE_AMD64 = 0x8664

_PE32, _PE32_PLUS = 0x10B, 0x20B
#: Offset of NumberOfRvaAndSizes in the optional header (the data directories follow it).
_RVA_COUNT_OFFSET = {_PE32: 92, _PE32_PLUS: 108}
_EXPORT_DIRECTORY, _IMPORT_DIRECTORY = 0, 1
_SECTION_HEADER_BYTES = 40
_IMPORT_DESCRIPTOR_BYTES = 20


@dataclass(frozen=True)
class PeImage:
    """machine: the COFF machine type (MACHINE_AMD64 for win64); exports: the names in the
    export name table; imports: the DLL names of the import directory, in table order."""
    machine: int
    exports: frozenset[str]
    imports: tuple[str, ...]


class _Reader:
    """Bounds-checked little-endian reads of a PE image, at file offsets or at RVAs."""

    def __init__(self, data: bytes):
        self.data = data
        self.sections: list[tuple[int, int, int]] = []  # (virtual address, size, raw offset)

    def unpack(self, fmt: str, offset: int) -> tuple:
        """struct.unpack_from('<' + fmt) at a file offset; ValueError when it lies outside the file."""
        if offset < 0 or offset + struct.calcsize("<" + fmt) > len(self.data):
            raise ValueError(f"truncated: {fmt} at offset {offset} is beyond the file's {len(self.data)} bytes")
        return struct.unpack_from("<" + fmt, self.data, offset)

    def offset(self, rva: int) -> int:
        """The file offset of relative virtual address `rva`; ValueError when no section holds it."""
        for address, size, raw in self.sections:
            if address <= rva < address + size:
                return rva - address + raw
        raise ValueError(f"address {rva:#x} is in no section")

    def string(self, rva: int) -> str:
        """The NUL-terminated ASCII string at `rva`."""
        start = self.offset(rva)
        end = self.data.find(b"\0", start)
        if end < 0:
            raise ValueError(f"unterminated name at {rva:#x}")
        return self.data[start:end].decode("ascii", errors="replace")


def read_pe(data: bytes) -> PeImage:
    """The machine type, exported names and imported DLLs of the PE image `data` (a .dll's
    bytes); ValueError naming the problem when it is not a well-formed PE32/PE32+ image."""
    r = _Reader(data)
    if data[:2] != b"MZ":
        raise ValueError("not a PE image (no MZ header)")
    pe = r.unpack("I", 0x3C)[0]
    if r.unpack("4s", pe)[0] != b"PE\0\0":
        raise ValueError("not a PE image (no PE signature)")
    machine, n_sections, _, _, _, optional_size, _ = r.unpack("HHIIIHH", pe + 4)
    optional = pe + 24
    magic = r.unpack("H", optional)[0]
    if magic not in _RVA_COUNT_OFFSET:
        raise ValueError(f"unknown optional-header magic {magic:#x}")
    n_directories = r.unpack("I", optional + _RVA_COUNT_OFFSET[magic])[0]
    directories = [r.unpack("II", optional + _RVA_COUNT_OFFSET[magic] + 4 + 8 * k)
                   for k in range(min(n_directories, _IMPORT_DIRECTORY + 1))]
    sections = optional + optional_size
    for k in range(n_sections):
        _, virtual_size, address, raw_size, raw = r.unpack("8sIIII", sections + k * _SECTION_HEADER_BYTES)
        r.sections.append((address, max(virtual_size, raw_size), raw))
    return PeImage(machine, frozenset(_exports(r, directories)), tuple(_imports(r, directories)))


def _exports(r: _Reader, directories: list[tuple[int, int]]) -> list[str]:
    """The names of the export name table (none without an export directory)."""
    if len(directories) <= _EXPORT_DIRECTORY or directories[_EXPORT_DIRECTORY][0] == 0:
        return []
    directory = r.offset(directories[_EXPORT_DIRECTORY][0])
    n_names, names = r.unpack("II", directory + 24)[0], r.unpack("I", directory + 32)[0]
    table = r.offset(names) if n_names else 0
    return [r.string(r.unpack("I", table + 4 * k)[0]) for k in range(n_names)]


def _imports(r: _Reader, directories: list[tuple[int, int]]) -> list[str]:
    """The DLL names of the import directory, up to its all-zero terminating descriptor."""
    if len(directories) <= _IMPORT_DIRECTORY or directories[_IMPORT_DIRECTORY][0] == 0:
        return []
    descriptor, dlls = r.offset(directories[_IMPORT_DIRECTORY][0]), []
    while (name := r.unpack("I", descriptor + 12)[0]) != 0:
        dlls.append(r.string(name))
        descriptor += _IMPORT_DESCRIPTOR_BYTES
    return dlls
