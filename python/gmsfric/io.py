"""Reading measurement files (CSV with a header row, or MATLAB .mat) and writing outputs
atomically.

Columns are always named explicitly by the caller (``--time t --position qm``); nothing is
guessed.  In a .mat file a struct's fields are named as in MATLAB (``log.q``, nested
``log.joint3.tau``) and a matrix's columns likewise (``q(:,3)``; a matrix with more columns than
rows holds its signals in rows, ``q(3,:)``).  Files saved with ``-v7`` or older are read by
scipy, ``-v7.3`` (HDF5) files with h5py when it is installed.  The units a CSV states (a units
row, or a header ending in a unit, ``x [mm]``) are checked against the units the caller declares
(:meth:`Table.check_unit`).  Problems raise
:class:`~gmsfric.errors.DataError` naming the file and the column.
Every output file is written to a temporary file in its directory and renamed over the target
(:func:`write_text_atomic`, :func:`atomic_path`), so a crash or Ctrl-C never leaves half a file.
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import os
import re
import stat
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np
from numpy.typing import NDArray

from . import units as units_module
from ._validate import within_fit_range
from .errors import DataError, OutputPathError


@dataclass
class Table:
    """Named columns (equal-length 1-D arrays) and scalars read from one file."""

    source: str
    columns: dict[str, NDArray[np.float64]]
    scalars: dict[str, float] = field(default_factory=dict)
    #: Shapes of the matrices of a .mat file, whose columns (or rows) are in ``columns``.
    matrices: dict[str, tuple[int, int]] = field(default_factory=dict)
    #: Units a CSV file states for its columns: in a row under the header (``s,mm,N``) or at the
    #: end of a column's name (``x [mm]``, ``F (N)``).
    units: dict[str, str] = field(default_factory=dict)

    def check_unit(self, name: str, declared: str, quantity: str, argument: str) -> None:
        """Refuse a column whose unit in the file differs from the one the caller declared for
        it: the values would be converted by the wrong factor (a 1000 in mm for m)."""
        written = self.units.get(name, "")
        if written in ("", "-"):
            return
        try:
            in_file = units_module.parse(written)
        except units_module.UnitError:
            raise DataError(f"{self.source}: column {name!r} is labelled {written!r} in the file's units row, a unit gmsfric "
                            f"cannot read; convert the column to a unit it reads or correct the label") from None
        given = units_module.check(declared, quantity, name=argument)
        same = in_file.dim == given.dim and abs(in_file.factor - given.factor) <= 1e-12 * abs(given.factor)
        if not same:
            scale = f" (the values would be off by a factor {in_file.factor / given.factor:.6g})" if in_file.dim == given.dim else ""
            raise DataError(f"{self.source}: column {name!r} is in {written} by the file, but `{argument}` is "
                            f"{declared!r}{scale}; declare it as {written}")

    def column(self, name: str, role: str = "column") -> NDArray[np.float64]:
        """The column ``name`` (raises ``DataError`` listing the available ones)."""
        key = name if name in self.columns else "".join(name.split())  # ``q(:, 3)`` as ``q(:,3)``
        if key not in self.columns:
            if key in self.matrices:
                rows, cols = self.matrices[key]
                example = f"{key}(:,1)" if rows >= cols else f"{key}(1,:)"
                raise DataError(f"{self.source}: {role} {name!r} is a {rows}x{cols} matrix; name one of its signals, e.g. {example}")
            avail = ", ".join(sorted(self.columns)) or "none"
            raise DataError(f"{self.source}: unknown {role} column {name!r}; available columns: {avail}")
        return self.columns[key]

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


#: Formats read as binary; everything else must be UTF-8 text.
BINARY_SUFFIXES = (".mat",)


def check_input_file(path: str | Path, *, role: str = "file") -> Path:
    """Check that ``path`` is a readable regular file with content, and, unless it is a
    ``.mat`` file, UTF-8 text (not UTF-16, not binary).

    Raises
    ------
    DataError
        Naming the file and what is wrong with it.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise DataError(f"the {role} must be a path (str or pathlib.Path), got {type(path).__name__}")
    p = Path(path)
    if not p.exists():
        raise DataError(f"{p}: no such file")
    if p.is_dir():
        raise DataError(f"{p}: is a directory, not a {role}")
    if not p.is_file():
        raise DataError(f"{p}: not a regular file")
    if not os.access(p, os.R_OK):
        raise DataError(f"{p}: permission denied")
    if p.stat().st_size == 0:
        raise DataError(f"{p}: file is empty")
    if p.suffix.lower() not in BINARY_SUFFIXES:
        with p.open("rb") as fh:
            head = fh.read(8192)
        if head[:2] in (b"\xff\xfe", b"\xfe\xff"):
            raise DataError(f"{p}: UTF-16 text; save it as UTF-8")
        if b"\x00" in head:
            # UTF-16 without a byte-order mark: every other byte of ASCII text is zero
            if max(head[0::2].count(0), head[1::2].count(0)) > len(head) // 3:
                raise DataError(f"{p}: looks like UTF-16 text; save it as UTF-8")
            raise DataError(f"{p}: binary file, expected text (CSV with a header row, JSON) or a .mat file")
        try:
            head.decode("utf-8")
        except UnicodeDecodeError as exc:
            if exc.start < len(head) - 4:  # not just a character cut at the end of the sample
                raise DataError(f"{p}: not UTF-8 text (byte {exc.start}); save it as UTF-8") from None
    return p


#: A line whose first field starts with one of these is a comment (a logger's preamble).
COMMENT_PREFIXES = ("#", "%")


def _is_unit(text: str) -> bool:
    try:
        units_module.parse(text)
    except units_module.UnitError:
        return False
    return True


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


#: A date and time as loggers write it (ISO 8601, UTC or local, no offset): a time column of
#: stamps is read as seconds from its first stamp.
TIMESTAMP = re.compile(r"^\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(:\d{2}(\.\d+)?)?Z?$")


#: Lines read to find a CSV's layout (preamble, header, units row, delimiter) before the data.
CSV_LAYOUT_LINES = 2000


@dataclass
class _CsvLayout:
    header: list[str]
    units: dict[str, str]
    data_start: int  # index of the first data line among the file's lines
    dialect: type[csv.Dialect] | csv.Dialect
    decimal_comma: bool


def _csv_layout(path: Path, lines: list[str]) -> _CsvLayout:
    """Where a CSV's header, units row and data are, from its first ``lines``."""
    content = [i for i, line in enumerate(lines) if line.strip()]
    k = 0
    while k < len(content) and lines[content[k]].lstrip().startswith(COMMENT_PREFIXES):
        k += 1
    if k == len(content):
        raise DataError(f"{path}: file is empty" if not content else f"{path}: no data in the first {len(lines)} lines, only comments")
    # The last comment line is the header when the data follow it directly: numpy's savetxt
    # writes "# t,q,f", a ROS bag exported to CSV "%time,field.position"
    header_text = lines[content[k]]
    fields = re.split(r"[,;\t ]+", header_text.strip())
    named = lines[content[k - 1]].lstrip()[1:].strip() if k > 0 else ""
    if all(_is_number(c) for c in fields) and len(re.split(r"[,;\t ]+", named)) == len(fields):
        header_text, k = named + "\n", k - 1
    rest = [lines[i] for i in content[k + 1:] if not lines[i].lstrip().startswith(COMMENT_PREFIXES)][:50]
    try:
        dialect: type[csv.Dialect] | csv.Dialect = csv.Sniffer().sniff(header_text + "".join(rest), delimiters=",;\t ")
    except csv.Error:
        dialect = csv.excel
    try:
        header = [h.strip() for h in next(csv.reader([header_text], dialect))]
        first = next(csv.reader(rest[:1], dialect), [])
    except csv.Error as exc:
        raise DataError(f"{path}: cannot read as CSV: {exc}") from None
    if all(_is_number(h) for h in header):
        raise DataError(f"{path}: the first row holds numbers, not column names; add a header row naming the columns (e.g. t,q,f)")
    data_start = content[k] + 1
    units: dict[str, str] = {}
    if first and len(first) == len(header) and not any(_is_number(c) or _is_number(c.replace(",", ".")) for c in first):
        # a row of units under the header (``s,mm,N`` or ``[s],[mm],[N]``): checked against the declared units
        units = {h: c.strip().strip("[]()").strip() for h, c in zip(header, first)}
        data_start = next(i for i in content if i > content[k] and not lines[i].lstrip().startswith(COMMENT_PREFIXES)) + 1
    for h in header:
        # a name ending in a unit, "x [mm]": a label that is no unit ("F (filtered)") says nothing
        label = re.search(r"[\[(]\s*([^\[\]()]+?)\s*[\])]\s*$", h)
        if h not in units and label is not None and _is_unit(label.group(1)):
            units[h] = label.group(1)
    decimal_comma = dialect.delimiter != "," and any("," in c and not _is_number(c) for c in first)
    return _CsvLayout(header, units, data_start, dialect, decimal_comma)


def _read_csv(path: Path) -> Table:
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            lines = list(itertools.islice(fh, CSV_LAYOUT_LINES))
            layout = _csv_layout(path, lines)
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not UTF-8 text (byte {exc.start}); save it as UTF-8") from None
    data = None if layout.decimal_comma else _loadtxt(path, layout)
    if data is None:  # numpy's reader refused: read again slowly to say where and why
        data = _parse_rows(path, layout)
    if data.shape[0] == 0:
        raise DataError(f"{path}: no data rows under the header")
    return Table(str(path), {h: np.ascontiguousarray(data[:, i]) for i, h in enumerate(layout.header)}, units=layout.units)


def _loadtxt(path: Path, layout: _CsvLayout) -> NDArray[np.float64] | None:
    """The data block by numpy's C reader (a log of millions of rows in seconds), or ``None``
    when it cannot read it as it is laid out."""
    delimiter = None if layout.dialect.delimiter == " " else layout.dialect.delimiter
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy warns on a file without data rows
            # one comment character, since numpy reads quoted fields only then ('%' lines go the slow way)
            data = np.loadtxt(path, delimiter=delimiter, skiprows=layout.data_start, comments="#", ndmin=2,
                              encoding="utf-8-sig", quotechar='"')
    except ValueError:
        return None
    return data if data.shape[1] == len(layout.header) or data.size == 0 else None


def _parse_rows(path: Path, layout: _CsvLayout) -> NDArray[np.float64]:
    """The data block parsed row by row: decimal commas, and faults named by row and column."""
    header = layout.header
    with path.open(newline="", encoding="utf-8-sig") as fh:
        lines = [line for line in itertools.islice(fh, layout.data_start, None) if line.strip() and not line.lstrip().startswith(COMMENT_PREFIXES)]
    try:
        body = [r for r in csv.reader(lines, layout.dialect) if any(cell.strip() for cell in r)]
    except csv.Error as exc:
        raise DataError(f"{path}: cannot read as CSV: {exc}") from None
    for i, r in enumerate(body):
        if len(r) != len(header):
            raise DataError(f"{path}: data row {i + 1} has {len(r)} fields, the header {len(header)}")
    dot = (lambda c: c.replace(",", ".")) if layout.decimal_comma else (lambda c: c)
    stamped = [j for j, c in enumerate(body[0] if body else []) if TIMESTAMP.match(c.strip())]
    for j in stamped:
        # date-and-time stamps become seconds from the first one, and the column's unit s
        odd = next((i for i, r in enumerate(body) if not TIMESTAMP.match(r[j].strip())), None)
        if odd is not None:
            raise DataError(f"{path}: data row {odd + 1}, column {header[j]!r}: {body[odd][j].strip()!r} is not a date and time like the first row's")
        try:
            stamps = np.array([r[j].strip().removesuffix("Z") for r in body], dtype="datetime64[ns]")
        except ValueError as exc:  # matches the pattern, yet no date (a 13th month)
            raise DataError(f"{path}: column {header[j]!r}: {exc}") from None
        seconds = (stamps - stamps[0]).astype(np.int64) / 1e9
        for r, value in zip(body, seconds):
            r[j] = repr(float(value))
        layout.units[header[j]] = "s"
    try:
        return np.array([[float(dot(c)) for c in r] for r in body], dtype=float).reshape(len(body), len(header))
    except ValueError:
        i, j = next((i, j) for i, r in enumerate(body) for j, c in enumerate(r) if not _is_number(dot(c)))
        what = "empty" if not body[i][j].strip() else f"{body[i][j].strip()!r} is not a number"
        raise DataError(f"{path}: data row {i + 1}, column {header[j]!r}: {what}") from None


def _read_mat(path: Path) -> Table:
    from scipy.io import loadmat

    try:
        raw = loadmat(str(path), simplify_cells=True)
    except NotImplementedError:  # scipy's answer to a -v7.3 (HDF5) file
        return _read_mat73(path)
    except Exception as exc:  # scipy raises several types for corrupt files
        raise DataError(f"{path}: cannot read as a MATLAB file: {exc}") from None
    table = Table(str(path), {})
    skipped: list[str] = []
    for key, value in raw.items():
        if not key.startswith("__"):
            _add_mat_value(table, key, value, skipped)
    return _checked_mat(table, skipped)


def _add_mat_value(table: Table, name: str, value: object, skipped: list[str]) -> None:
    """Add a MATLAB variable (as scipy's ``simplify_cells`` gives it) to ``table``: a struct
    field by field, a real number as a scalar, a vector as a column, a matrix signal by signal.
    What holds no real numbers (text, cells, struct arrays, objects such as a ``timeseries``,
    complex values) is named in ``skipped``."""
    if isinstance(value, dict):
        for key, field_value in value.items():
            _add_mat_value(table, f"{name}.{key}", field_value, skipped)
        return
    if isinstance(value, (bool, int, float, np.bool_, np.integer, np.floating)):
        table.scalars[name] = float(value)
        return
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "fiub" or value.size == 0:
        skipped.append(name)
        return
    arr = np.asarray(value, dtype=float).squeeze()
    if arr.size == 1:
        table.scalars[name] = float(arr.reshape(-1)[0])
    elif arr.ndim == 1:
        table.columns[name] = np.ascontiguousarray(arr)
    elif arr.ndim == 2:
        rows, cols = arr.shape
        table.matrices[name] = (rows, cols)
        if rows >= cols:  # signals in columns, the usual layout of a log
            for j in range(cols):
                table.columns[f"{name}(:,{j + 1})"] = np.ascontiguousarray(arr[:, j])
        else:
            for i in range(rows):
                table.columns[f"{name}({i + 1},:)"] = np.ascontiguousarray(arr[i, :])
    else:
        skipped.append(name)


def _read_mat73(path: Path) -> Table:
    """A MATLAB ``-v7.3`` file (HDF5): groups are structs, datasets arrays (stored transposed:
    MATLAB writes column-major)."""
    try:
        import h5py
    except ImportError:
        raise DataError(f"{path}: a MATLAB -v7.3 (HDF5) file; install h5py (pip install h5py) to read it, "
                        "or save it in MATLAB with save(..., '-v7')") from None
    table = Table(str(path), {})
    skipped: list[str] = []

    def visit(group: "h5py.Group", prefix: str) -> None:
        for key, item in group.items():
            if key.startswith("#"):  # MATLAB's store of cell contents and object references
                continue
            name = f"{prefix}.{key}" if prefix else key
            if isinstance(item, h5py.Group):
                visit(item, name)
                continue
            kind = item.attrs.get("MATLAB_class", b"double")
            kind = kind.decode() if isinstance(kind, bytes) else str(kind)
            if kind in ("char", "cell") or item.attrs.get("MATLAB_empty", 0):
                skipped.append(name)
                continue
            _add_mat_value(table, name, np.asarray(item[()]).T, skipped)

    try:
        with h5py.File(path, "r") as fh:
            visit(fh, "")
    except (OSError, ValueError) as exc:
        raise DataError(f"{path}: cannot read as a MATLAB -v7.3 file: {exc}") from None
    return _checked_mat(table, skipped)


def _checked_mat(table: Table, skipped: list[str]) -> Table:
    if not table.columns:
        hint = f" (not read: {', '.join(skipped[:8])}; text, cells, objects such as a timeseries and complex values are not signals)" if skipped else ""
        raise DataError(f"{table.source}: no numeric vectors in the file{hint}")
    return table


def read_table(path: str | Path) -> Table:
    """Read a CSV (header row) or .mat file into a :class:`Table`."""
    p = check_input_file(path)
    return _read_mat(p) if p.suffix.lower() == ".mat" else _read_csv(p)


def load_columns(path: str | Path | Table, mapping: Mapping[str, str], *, min_samples: int = 10,
                 repeated_time: bool = False, declared_units: Mapping[str, tuple[str, str, str]] | None = None) -> dict[str, NDArray[np.float64]]:
    """Columns by role, e.g. ``load_columns(f, {"time": "t", "position": "qm"})``.

    Checks that every column exists, all have the same length, there are at least
    ``min_samples`` rows, values are finite, and a ``time`` role increases strictly (never
    decreases, with ``repeated_time``: for a caller that merges samples logged under one stamp).
    ``declared_units`` maps a role to ``(unit, quantity, argument)``, the unit the caller was
    given for it: a file that states another unit for that column (a units row, or the column's
    name ending in one, ``x [mm]``) is refused.
    """
    table = path if isinstance(path, Table) else read_table(path)
    out = {role: table.column(name, role) for role, name in mapping.items()}
    for role, (unit, quantity, argument) in (declared_units or {}).items():
        if role in mapping:
            table.check_unit(mapping[role], unit, quantity, argument)
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
    step = None
    if "time" in out:
        d = np.diff(out["time"])
        wrong = d < 0 if repeated_time else d <= 0
        if np.any(wrong):
            i = int(np.flatnonzero(wrong)[0]) + 1
            raise DataError(f"{table.source}: time column {mapping['time']!r} is not strictly increasing at row {i}")
        step = float(np.min(d[d > 0], initial=np.inf))
    for role, a in out.items():
        within_fit_range(f"{table.source}: column {mapping[role]!r} ({role})", a, error=DataError)
    if step is not None and np.isfinite(step) and "position" in out:
        within_fit_range(f"{table.source}: column {mapping['position']!r} (position)", out["position"], time_step=step, error=DataError)
    return out


# ------------------------------------------------------------------------------------------
# atomic outputs


def _new_file_mode(target: Path) -> int:
    if target.exists():
        return target.stat().st_mode & 0o777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def check_output_path(path: str | Path, *, name: str = "path") -> Path:
    """Check that ``path`` can receive an output file before any work: a path (str or Path), not
    a directory (nor a name ending in a separator), in an existing directory.  A symbolic link is
    checked (and later written) through to its target.

    Raises
    ------
    OutputPathError
        Naming the argument ``name`` and the user's path.
    """
    if not isinstance(path, (str, os.PathLike)) or isinstance(path, bytes):
        raise OutputPathError(f"`{name}` must be a path (str or pathlib.Path), got {type(path).__name__}")
    text = os.fspath(path)
    if not isinstance(text, str) or not text.strip():
        raise OutputPathError(f"`{name}` must be a file name, got {text!r}")
    p = Path(text)
    if p.is_dir():
        raise OutputPathError(f"`{name}` {text}: is a directory; give a file name")
    if text.endswith(("/", os.sep)):
        raise OutputPathError(f"`{name}` {text}: ends with '/', a directory name; give a file name")
    real = Path(os.path.realpath(p)) if p.is_symlink() else p
    parent = real.parent
    if not parent.exists():
        raise OutputPathError(f"`{name}` {text}: directory {parent} does not exist")
    if not parent.is_dir():
        raise OutputPathError(f"`{name}` {text}: {parent} is not a directory")
    return p


def _reraise_for(exc: OSError, target: Path) -> OSError:
    """The same error naming the user's path, never a temporary file's."""
    return type(exc)(exc.errno, exc.strerror or str(exc), str(target)) if exc.errno is not None else exc


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path in the directory of ``path``; on success it is renamed over ``path``
    (``os.replace``), on error removed.  The target is untouched until the rename::

        with atomic_path("fig.png") as tmp:
            fig.savefig(tmp, format="png")

    Only a regular file (or a new name) is replaced that way.  A symbolic link is written
    through to the file it points to (the link stays); an existing target that is not a regular
    file (``/dev/null``, a FIFO) is written directly, never replaced.

    Raises
    ------
    OutputPathError
        ``path`` is a directory, its directory does not exist, or no file can be created in it
        (a ``ValueError``).
    OSError
        A write or rename error, naming ``path`` (never the temporary file).
    """
    given = check_output_path(path)
    target = Path(os.path.realpath(given)) if given.is_symlink() else given
    if target.exists() and not target.is_file():
        # a device or a FIFO: there is nothing to keep whole, and a rename would replace the node
        yield target
        return
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent if str(target.parent) else ".")
        os.close(fd)
    except OSError as exc:
        # the file is written beside its target, then renamed over it
        raise OutputPathError(f"`path` {given}: cannot create a file in {target.parent} ({exc.strerror or exc})") from None
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, _new_file_mode(target))
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.filename is not None and str(exc.filename) in (str(tmp), name):
            raise _reraise_for(exc, given) from None
        raise


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_path`); returns the path.

    Raises
    ------
    OSError
        Including a full device (``ENOSPC``), naming ``path``.
    """
    with atomic_path(path) as tmp:
        try:
            with open(tmp, "w", encoding="utf-8") as fh:
                fh.write(text)
                fh.flush()
                if stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                    os.fsync(fh.fileno())
        except OSError as exc:
            raise _reraise_for(exc, Path(path)) from None
    return Path(path)
