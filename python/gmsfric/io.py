"""Reading measurement files: CSV with a header row, or MATLAB .mat (v5, via scipy).

Columns are always named explicitly by the caller (``--time t --position qm``); nothing is
guessed.  Problems raise :class:`~gmsfric.errors.DataError` naming the file and the column.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np
from numpy.typing import NDArray

from .errors import DataError


@dataclass
class Table:
    """Named columns (equal-length 1-D arrays) and scalars read from one file."""

    source: str
    columns: dict[str, NDArray[np.float64]]
    scalars: dict[str, float] = field(default_factory=dict)

    def column(self, name: str, role: str = "column") -> NDArray[np.float64]:
        """The column ``name`` (raises ``DataError`` listing the available ones)."""
        if name not in self.columns:
            avail = ", ".join(sorted(self.columns)) or "none"
            raise DataError(f"{self.source}: unknown {role} column {name!r}; available columns: {avail}")
        return self.columns[name]

    def number(self, spec: str | float, role: str = "gain") -> float:
        """A number given literally or as the name of a scalar (or constant column) in the file."""
        try:
            value = float(spec)
        except (TypeError, ValueError):
            name = str(spec)
            if name in self.scalars:
                value = self.scalars[name]
            elif name in self.columns and np.ptp(self.columns[name]) == 0:
                value = float(self.columns[name][0])
            else:
                avail = ", ".join(sorted(self.scalars)) or "none"
                raise DataError(f"{self.source}: {role} {name!r} is neither a number nor a scalar in the file; scalars: {avail}") from None
        if not np.isfinite(value):
            raise DataError(f"{self.source}: {role} must be finite, got {value}")
        return value

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0


def _read_csv(path: Path) -> Table:
    with path.open(newline="") as fh:
        sample = fh.read(4096)
        fh.seek(0)
        try:
            dialect = csv.Sniffer().sniff(sample, delimiters=",;\t ")
        except csv.Error:
            dialect = csv.excel  # type: ignore[assignment]
        rows = list(csv.reader(fh, dialect))
    rows = [r for r in rows if any(cell.strip() for cell in r)]
    if not rows:
        raise DataError(f"{path}: file is empty")
    header = [h.strip() for h in rows[0]]
    if len(rows) < 2:
        raise DataError(f"{path}: no data rows under the header")
    try:
        data = np.array([[float(c) for c in r] for r in rows[1:]], dtype=float)
    except ValueError as exc:
        raise DataError(f"{path}: non-numeric value in the data rows ({exc}); is the first row a header?") from None
    if data.ndim != 2 or data.shape[1] != len(header):
        raise DataError(f"{path}: rows do not all have {len(header)} fields like the header")
    return Table(str(path), {h: np.ascontiguousarray(data[:, i]) for i, h in enumerate(header)})


def _read_mat(path: Path) -> Table:
    from scipy.io import loadmat

    try:
        raw = loadmat(str(path))
    except Exception as exc:  # scipy raises several types for corrupt files
        raise DataError(f"{path}: cannot read as a MATLAB file: {exc}") from None
    columns: dict[str, NDArray[np.float64]] = {}
    scalars: dict[str, float] = {}
    for key, value in raw.items():
        if key.startswith("__") or not isinstance(value, np.ndarray) or value.dtype.kind not in "fiub":
            continue
        arr = np.asarray(value, dtype=float).squeeze()
        if arr.ndim == 0 or arr.size == 1:
            scalars[key] = float(arr.reshape(-1)[0])
        elif arr.ndim == 1:
            columns[key] = np.ascontiguousarray(arr)
    if not columns:
        raise DataError(f"{path}: no numeric vectors in the file")
    return Table(str(path), columns, scalars)


def read_table(path: str | Path) -> Table:
    """Read a CSV (header row) or .mat file into a :class:`Table`."""
    p = Path(path)
    if not p.exists():
        raise DataError(f"{p}: no such file")
    if p.stat().st_size == 0:
        raise DataError(f"{p}: file is empty")
    return _read_mat(p) if p.suffix.lower() == ".mat" else _read_csv(p)


def load_columns(path: str | Path | Table, mapping: Mapping[str, str], *, min_samples: int = 10) -> dict[str, NDArray[np.float64]]:
    """Columns by role, e.g. ``load_columns(f, {"time": "t", "position": "qm"})``.

    Checks that every column exists, all have the same length, there are at least
    ``min_samples`` rows, values are finite, and a ``time`` role increases strictly.
    """
    table = path if isinstance(path, Table) else read_table(path)
    out = {role: table.column(name, role) for role, name in mapping.items()}
    lengths = {role: a.size for role, a in out.items()}
    if len(set(lengths.values())) > 1:
        raise DataError(f"{table.source}: columns have different lengths: {lengths}")
    n = next(iter(lengths.values()), 0)
    if n < min_samples:
        raise DataError(f"{table.source}: too few samples ({n}); need at least {min_samples}")
    for role, a in out.items():
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise DataError(f"{table.source}: column {mapping[role]!r} ({role}) has a non-finite value at row {bad[0]}")
    if "time" in out:
        d = np.diff(out["time"])
        if np.any(d <= 0):
            i = int(np.flatnonzero(d <= 0)[0]) + 1
            raise DataError(f"{table.source}: time column {mapping['time']!r} is not strictly increasing at row {i}")
    return out
