"""Progress: tqdm on a terminal, nothing at all on a pipe or a log file."""

from __future__ import annotations

import io

from gmsfric._progress import Progress


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_silent_off_a_terminal():
    s = io.StringIO()
    with Progress("fit", total=5, stream=s, every=0.0) as p:
        for _ in range(5):
            p.update(note="round 1")
    assert s.getvalue() == "" and p.count == 5 and not p.active


def test_draws_on_a_terminal_or_when_forced_and_never_when_disabled():
    for stream, kwargs in ((_Tty(), {}), (io.StringIO(), {"force": True})):
        with Progress("fit", total=3, stream=stream, every=0.0, **kwargs) as p:
            p.update(2, note="stage a")
        assert "fit" in stream.getvalue() and "stage a" in stream.getvalue()
    t = _Tty()
    with Progress("fit", total=3, stream=t, enabled=False) as p:
        p.update()
    assert t.getvalue() == ""
