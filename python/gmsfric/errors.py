"""Exception hierarchy of gmsfric.

``GmsfricError`` is the base of everything gmsfric raises on purpose.  Bad arguments raise
``InvalidInputError``, which is also a ``ValueError`` (as in python-control), so
``except ValueError`` keeps working.  Runs that produce non-finite values raise
``SimulationError``; work that cannot fit in memory ``ResourceError`` (a ``MemoryError``); a run
interrupted by Ctrl-C ``KeyboardInterrupt``.  The compiled core raises the same classes.
"""

from __future__ import annotations

from ._gmsfric import GmsfricError, InvalidInputError, ResourceError, SimulationError


class DataError(InvalidInputError):
    """A data file or table cannot be used: unknown column, empty, non-numeric, too short."""


class IdentificationError(GmsfricError, RuntimeError):
    """An identification could not produce a trustworthy result (too few points, no convergence)."""


__all__ = ["GmsfricError", "InvalidInputError", "SimulationError", "ResourceError", "DataError", "IdentificationError"]
