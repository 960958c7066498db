"""The result protocol shared by the identify, loop and glitch wings.

Every result object offers

* ``to_dict()``: the JSON document, i.e. the wing's own fields plus an envelope:
  ``"schema"`` (:data:`SCHEMA`), ``"kind"``, ``"gmsfric_version"``, ``"provenance"`` (input
  files, the columns used, the declared units, the command line) and ``"diagnostics"`` (a list);
* ``table() -> str``: the plain-text report;
* ``plot() -> dict[str, Figure]``: figures by file stem (matplotlib ``Figure``, no pyplot);
* ``to_json(path=None)``: the JSON text, written atomically when ``path`` is given;
* ``save(directory)``: every figure as ``<stem>.png`` and the JSON as ``<kind>.json``.

Wings implement ``_body()`` (their existing fields, a contract), ``table()`` and ``plot()`` and
inherit the rest from :class:`Result`.  :func:`jsonable` is the package's one conversion of
numpy values to plain JSON (non-finite floats become ``null``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Mapping, Sequence

import numpy as np

from .io import atomic_path, write_text_atomic

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

SCHEMA = "gmsfric.result/1"
ENVELOPE_KEYS = ("schema", "kind", "gmsfric_version", "provenance", "diagnostics")

__all__ = ["SCHEMA", "Result", "jsonable", "envelope", "provenance", "write_figures", "dumps"]


def jsonable(value: Any) -> Any:
    """Plain-JSON version of ``value``: mappings, sequences, numpy arrays and scalars, paths and
    dataclasses are converted; non-finite floats become ``None``."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [jsonable(v) for v in value.tolist()]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, Path):
        return str(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return jsonable(dataclasses.asdict(value))
    return value


def dumps(document: Any, *, indent: int | None = 2) -> str:
    """Strict JSON text of ``document`` (after :func:`jsonable`; never ``NaN`` or ``Infinity``)."""
    return json.dumps(jsonable(document), indent=indent, allow_nan=False)


def provenance(
    *,
    command: str | None = None,
    input_files: Sequence[Mapping[str, Any]] | None = None,
    columns: Mapping[str, Any] | None = None,
    units: Mapping[str, str] | None = None,
    **extra: Any,
) -> dict[str, Any]:
    """A provenance record: the command line, the input files (path, size, sha256), the columns
    used (role -> column) and the declared units (role -> unit), plus any ``extra`` fields."""
    out: dict[str, Any] = {
        "command": command,
        "input_files": [dict(f) for f in (input_files or [])],
        "columns": dict(columns or {}),
        "units": dict(units or {}),
    }
    out.update(extra)
    return out


def _merge_provenance(*records: Mapping[str, Any] | None) -> dict[str, Any]:
    """One provenance record from several (later ones override; columns and units merge)."""
    out = provenance()
    for r in records:
        for k, v in (r or {}).items():
            if k in ("columns", "units") and isinstance(v, Mapping):
                out[k] = {**out[k], **v}
            elif v is not None:
                out[k] = v
    return out


def envelope(kind: str, body: Mapping[str, Any], *, provenance: Mapping[str, Any] | None = None,
             diagnostics: Sequence[Any] | None = None) -> dict[str, Any]:
    """``body`` with the envelope fields added beside it (the body's own fields are kept as they
    are; a body field with an envelope name is an error)."""
    from . import __version__

    clash = [k for k in ENVELOPE_KEYS if k in body]
    if clash:
        raise ValueError(f"result fields {clash} collide with the JSON envelope")
    out = dict(body)
    out.update(
        schema=SCHEMA,
        kind=kind,
        gmsfric_version=__version__,
        provenance=_merge_provenance(provenance),
        diagnostics=list(diagnostics or []),
    )
    return out


def write_figures(figures: Mapping[str, "Figure"], directory: str | Path, *, dpi: int = 110) -> list[Path]:
    """Save ``{stem: Figure}`` as ``directory/<stem>.png`` (each atomically; the directory is
    created).  Returns the paths."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    paths = []
    for stem, fig in figures.items():
        p = d / f"{stem}.png"
        with atomic_path(p) as tmp:
            fig.savefig(tmp, format="png", dpi=dpi)
        paths.append(p)
    return paths


class Result:
    """Mixin of the shared protocol (see the module docstring).

    Subclasses set ``kind``, implement ``_body()``, ``table()`` and ``plot()``, and may override
    ``_extras()`` for fields added beside the envelope (e.g. an embedded model document).  They
    may carry ``provenance`` (a dict) and ``diagnostics`` (a list) attributes.
    """

    kind: ClassVar[str] = "result"

    def _body(self) -> dict[str, Any]:  # pragma: no cover - every wing implements it
        raise NotImplementedError

    def _extras(self) -> dict[str, Any]:
        return {}

    def table(self) -> str:  # pragma: no cover - every wing implements it
        raise NotImplementedError

    def plot(self) -> dict[str, "Figure"]:
        """The figures of this result by file stem (matplotlib ``Figure`` objects, no pyplot)."""
        return {}

    def to_dict(self) -> dict[str, Any]:
        """The JSON document: the result's fields, the envelope and any extras."""
        doc = envelope(self.kind, self._body(), provenance=getattr(self, "provenance", None), diagnostics=getattr(self, "diagnostics", None))
        for k, v in self._extras().items():
            if k in doc:
                raise ValueError(f"extra field {k!r} collides with a result field")
            doc[k] = v
        return doc

    def to_json(self, path: str | Path | None = None, *, indent: int = 2) -> str:
        """The JSON text of :meth:`to_dict`; also written (atomically) to ``path`` when given."""
        text = dumps(self.to_dict(), indent=indent)
        if path is not None:
            write_text_atomic(path, text + "\n")
        return text

    def save(self, directory: str | Path) -> list[Path]:
        """Write every figure of :meth:`plot` as PNG and the JSON as ``<kind>.json`` into
        ``directory`` (created); returns the paths."""
        paths = write_figures(self.plot(), directory)
        p = Path(directory) / f"{self.kind}.json"
        self.to_json(p)
        return paths + [p]

    def __str__(self) -> str:
        return self.table()
