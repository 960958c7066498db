"""Minimal progress reporting on stderr for long fits and sweeps (no dependency)."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """``with Progress("fitting", total=n) as p: ... p.update()``; silent when ``enabled`` is False
    or the stream is not a terminal and ``force`` is not set."""

    def __init__(self, label: str, total: int | None = None, *, enabled: bool = True, stream: TextIO | None = None, every: float = 0.5) -> None:
        self.label, self.total, self.enabled = label, total, enabled
        self.stream = stream if stream is not None else sys.stderr
        self.every, self.count, self._last, self._t0 = every, 0, 0.0, time.monotonic()

    def update(self, n: int = 1, note: str = "") -> None:
        self.count += n
        now = time.monotonic()
        if self.enabled and (now - self._last >= self.every or (self.total is not None and self.count >= self.total)):
            self._last = now
            frac = f"{self.count}/{self.total}" if self.total else f"{self.count}"
            self.stream.write(f"\r{self.label}: {frac} ({now - self._t0:.1f} s) {note}".ljust(60))
            self.stream.flush()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        if self.enabled and self.count:
            self.stream.write("\n")
            self.stream.flush()
