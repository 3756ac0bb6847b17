"""Typed, validated access to one TOML table, with errors that name the file and the key."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from contract.errors import ScenarioError

#: Marks a key without default: it must be present.
REQUIRED = object()


def _is_number(value) -> bool:
    """True for int/float TOML values (TOML booleans are not numbers)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class TomlTable:
    """One table of a parsed TOML file. Every accessor records the key as known; `close()`
    rejects the keys nobody asked for (typos), so each table is read exactly once."""

    def __init__(self, raw, path: Path, where: str):
        self.path, self.where = Path(path), where
        if not isinstance(raw, dict):
            raise self._error(None, f"expected a table, got {type(raw).__name__}")
        self.raw, self.known = raw, set()

    def _error(self, key: str | None, problem: str) -> ScenarioError:
        """ScenarioError '<file>: [<table>] key '<key>': <problem>'."""
        at = f"[{self.where}]" if key is None else f"[{self.where}] key '{key}'"
        return ScenarioError(f"{self.path}: {at}: {problem}")

    def _get(self, key: str, default):
        self.known.add(key)
        if key in self.raw:
            return self.raw[key]
        if default is REQUIRED:
            raise self._error(key, "missing")
        return default

    def has(self, key: str) -> bool:
        """True when the table sets `key`."""
        return key in self.raw

    def number(self, key: str, default=REQUIRED, *, low: float | None = None,
               high: float | None = None, positive: bool = False) -> float:
        """A finite number, optionally within [low, high] or > 0."""
        value = self._get(key, default)
        if not _is_number(value) or not math.isfinite(value):
            raise self._error(key, f"expected a finite number, got {value!r}")
        if positive and value <= 0:
            raise self._error(key, f"must be > 0, got {value!r}")
        if low is not None and value < low:
            raise self._error(key, f"must be ≥ {low}, got {value!r}")
        if high is not None and value > high:
            raise self._error(key, f"must be ≤ {high}, got {value!r}")
        return float(value)

    def optional_number(self, key: str) -> float | None:
        """A finite number or None when absent."""
        self.known.add(key)
        return self.number(key) if self.has(key) else None

    def integer(self, key: str, default=REQUIRED, *, low: int = 0) -> int:
        """An integer ≥ low."""
        value = self._get(key, default)
        if not isinstance(value, int) or isinstance(value, bool) or value < low:
            raise self._error(key, f"expected an integer ≥ {low}, got {value!r}")
        return value

    def string(self, key: str, default=REQUIRED, *, choices: tuple[str, ...] | None = None,
               allow_empty: bool = False) -> str:
        """A string (non-empty unless allow_empty), optionally one of `choices`."""
        value = self._get(key, default)
        if not isinstance(value, str) or (not value and not allow_empty):
            raise self._error(key, f"expected a non-empty string, got {value!r}")
        if choices is not None and value not in choices:
            raise self._error(key, f"expected one of {', '.join(choices)}, got {value!r}")
        return value

    def array(self, key: str, shape: tuple[int | None, ...] = (None,), default=REQUIRED, *,
              positive: bool = False) -> np.ndarray:
        """A numeric array (float64) of `shape`; a None dimension takes any length ≥ 1."""
        value = self._get(key, default)
        flat = np.ravel(np.array(value, dtype=object)) if isinstance(value, list) else [value]
        if not isinstance(value, list) or any(not _is_number(v) for v in flat):
            raise self._error(key, f"expected a list of numbers, got {value!r}")
        array = np.array(value, dtype=float)
        wanted = tuple("n" if s is None else s for s in shape)
        if (array.ndim != len(shape) or array.size == 0
                or any(s is not None and s != n for s, n in zip(shape, array.shape))):
            raise self._error(key, f"expected shape {wanted}, got {value!r}")
        if not np.all(np.isfinite(array)) or (positive and np.any(array <= 0)):
            raise self._error(key, f"expected finite{' positive' if positive else ''} numbers, "
                                   f"got {value!r}")
        return array

    def strings(self, key: str, choices: tuple[str, ...] | None = None) -> tuple[str, ...]:
        """A non-empty list of non-empty strings, each one of `choices` (None: any)."""
        value = self._get(key, REQUIRED)
        allowed = (lambda v: v in choices) if choices is not None else (lambda v: isinstance(v, str) and v)
        if not isinstance(value, list) or not value or not all(allowed(v) for v in value):
            wanted = ", ".join(choices) if choices is not None else "strings"
            raise self._error(key, f"expected a non-empty list of {wanted}, got {value!r}")
        return tuple(value)

    def table(self, key: str) -> "TomlTable":
        """A required sub-table."""
        return TomlTable(self._get(key, REQUIRED), self.path, key if self.where == "top level"
                         else f"{self.where}.{key}")

    def tables(self, key: str) -> list["TomlTable"]:
        """A required, non-empty array of tables ([[key]])."""
        value = self._get(key, REQUIRED)
        if not isinstance(value, list) or not value:
            raise self._error(key, "expected at least one [[" + key + "]] table")
        return [TomlTable(v, self.path, f"{key} {i + 1}") for i, v in enumerate(value)]

    def fail(self, key: str, problem: str) -> ScenarioError:
        """An error about `key` for checks that span several keys."""
        return self._error(key, problem)

    def close(self) -> None:
        """Raise ScenarioError for the first key that no accessor asked for."""
        unknown = sorted(set(self.raw) - self.known)
        if unknown:
            raise self._error(unknown[0], "unknown key (misspelt?); known keys: "
                              + ", ".join(sorted(self.known)))
