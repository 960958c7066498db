"""Progress of long fits and sweeps on stderr, through tqdm.

Silent when disabled or when the stream is not a terminal (no ``\\r`` lines in log files), unless
``force`` is set.
"""

from __future__ import annotations

import sys
from typing import TextIO

from tqdm import tqdm


class Progress:
    """``with Progress("fitting", total=n) as p: ... p.update()``; silent when ``enabled`` is False
    or the stream is not a terminal and ``force`` is not set.

    Parameters
    ----------
    label : str
        Shown before the count.
    total : int, optional
        Expected number of updates (a bar when given, a counter otherwise).
    enabled : bool
        Show anything at all.
    stream : text stream, optional
        Default ``sys.stderr``.
    every : float
        Shortest time between redraws (s).
    force : bool
        Draw even when the stream is not a terminal.
    """

    def __init__(self, label: str, total: int | None = None, *, enabled: bool = True, stream: TextIO | None = None, every: float = 0.5,
                 force: bool = False) -> None:
        self.label, self.total, self.enabled = label, total, enabled
        self.stream = stream if stream is not None else sys.stderr
        self.count = 0
        isatty = getattr(self.stream, "isatty", None)
        tty = bool(isatty()) if callable(isatty) else False
        self._bar = tqdm(total=total, desc=label, file=self.stream, disable=not (enabled and (tty or force)), mininterval=every,
                         leave=False, dynamic_ncols=True)

    @property
    def active(self) -> bool:
        """Whether anything is drawn."""
        return not self._bar.disable

    def update(self, n: int = 1, note: str = "") -> None:
        """Count ``n`` more steps; ``note`` is shown after the count."""
        self.count += n
        if note and self.active:
            self._bar.set_postfix_str(note, refresh=False)
        self._bar.update(n)

    def close(self) -> None:
        self._bar.close()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
