"""The project's own error type: one clear line naming the file, row or column, and the problem."""

from __future__ import annotations

from pathlib import Path


class PipelineError(Exception):
    """Any refused input or impossible request.  ``str(err)`` is a single line.

    Parameters
    ----------
    message : what is wrong, in plain words.
    file : the file concerned (path or name), if any.
    row : 1-based line number in the file (header lines included), if known.
    column : column name, if the problem is in one column.
    """

    def __init__(self, message: str, *, file: str | Path | None = None, row: int | None = None,
                 column: str | None = None):
        self.message = " ".join(str(message).split())
        self.file = str(file) if file is not None else None
        self.row = row
        self.column = column
        super().__init__(self.__str__())

    def __str__(self) -> str:
        where = []
        if self.file:
            where.append(self.file)
        if self.row is not None:
            where.append(f"row {self.row}")
        if self.column:
            where.append(f"column '{self.column}'")
        prefix = ": ".join([", ".join(where)]) if where else ""
        return f"{prefix}: {self.message}" if prefix else self.message


class InputError(PipelineError):
    """Bad input data (docs/contract.md#bad-input)."""


class ModelError(PipelineError):
    """A model or parameter set that cannot be used (e.g. no real positive time constants)."""


class FilterError(PipelineError):
    """A numerical failure inside a filter (e.g. a failed Cholesky downdate)."""
