"""Exceptions that the CLI turns into one-line messages and a non-zero exit status."""


class ImuFusionError(Exception):
    """Base class of every error the user can cause (bad file, bad option, bad model)."""


class DataError(ImuFusionError):
    """A data file is malformed; the message names the file, the row/column and the problem."""

    def __init__(self, path, problem, row=None, column=None):
        self.path, self.problem, self.row, self.column = str(path), problem, row, column
        where = [self.path]
        if row is not None:
            where.append(f"row {row}")
        if column is not None:
            where.append(f"column '{column}'")
        super().__init__(f"{', '.join(where)}: {problem}")


class ModelError(ImuFusionError):
    """A model artefact is missing, malformed or of an unsupported format version."""


class ScenarioError(ImuFusionError):
    """A scenario file is missing or malformed; the message names the file and the key."""


class BuildError(ImuFusionError):
    """Compiling the C runtime or the FMU failed; the message carries the compiler output."""


def one_line(text: str) -> str:
    """`text` on one line: its non-blank lines joined by ' | ' (for messages that embed a tool's
    or an FMU's multi-line output)."""
    return " | ".join(line.strip() for line in str(text).splitlines() if line.strip())
