"""Exception hierarchy of gmsfric.

``GmsfricError`` is the base of everything gmsfric raises on purpose.  Bad arguments raise
``InvalidInputError``, which is also a ``ValueError`` (as in python-control), so
``except ValueError`` keeps working.  Runs that produce non-finite values raise
``SimulationError``; work that cannot fit in memory ``ResourceError`` (a ``MemoryError``); a run
interrupted by Ctrl-C ``KeyboardInterrupt``.  The compiled core raises the same classes.
A fit that ran but should not be trusted as it stands warns with ``FitWarning`` (a
``UserWarning``).
"""

from __future__ import annotations

from ._gmsfric import GmsfricError, InvalidInputError, ResourceError, SimulationError


class DataError(InvalidInputError):
    """A data file or table cannot be used: unknown column, empty, non-numeric, too short."""


class OutputPathError(InvalidInputError):
    """An output path that cannot receive a file: a directory (or a name ending in '/'), a
    directory that does not exist, or no path at all.  Raised before any work."""


class IdentificationError(GmsfricError, RuntimeError):
    """An identification could not produce a trustworthy result (too few points, no convergence)."""


class FitWarning(UserWarning):
    """A fit finished but a finding makes it less trustworthy than its table suggests: a
    parameter at a bound, a non-physical ordering, chi2/dof far from 1, a standard error over
    100 %, data that do not cover a parameter, saturated or closed-loop data."""


__all__ = ["GmsfricError", "InvalidInputError", "SimulationError", "ResourceError", "DataError", "OutputPathError", "IdentificationError", "FitWarning"]
