"""A hostile-input harness over gmsfric's public Python API, run in a worker process.

A generated call is plain data (nested ``call(name, *args, **kwargs)`` nodes whose arguments are
numbers, strings, lists, numpy arrays or other nodes); a worker process (this file run as a
script) builds and runs it and reports how it ended. The parent (:class:`Harness`) sees what the
worker cannot report itself: a dead worker (abort, segfault, a panic that kills the process), a
hang (no answer within the timeout); it then restarts the worker.

Outcomes (:data:`FAILURES` are the ones a test rejects):

``ok``         a result, every float in it finite
``error``      a clean error: a ``GmsfricError`` or a ``MemoryError``
``nonfinite``  a result holding a NaN or an infinity
``foreign``    a ``ValueError`` that is not a ``GmsfricError`` (says nothing about the argument)
``wrong``      any other exception escaping (``TypeError``, ``OverflowError``, ``AssertionError`` ...)
``panic``      a Rust panic reaching Python (``pyo3_runtime.PanicException``)
``died``       the worker process died (abort, segfault, killed)
``hang``       no answer within the timeout

The strategies (:func:`api_call` and the builders it uses) cover every public constructor and
simulation entry point with extreme but often valid values (subnormal, 1e308, -0.0, huge steps
and delays) and, parameter by parameter, hostile ones (nan, inf, huge ints, bools, strings,
None, wrong shapes). ``tests/test_fuzz_api.py`` runs a short fixed-seed profile in CI;
``benches/fuzz_api.py`` a long one that reports the counts.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pickle
import re
import select
import signal
import struct
import subprocess
import sys
import tempfile
import time
import traceback
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

CALL = "\x00call"
FAILURES = ("nonfinite", "foreign", "wrong", "panic", "died", "hang")
#: Per-call timeout (s): every generated call is small (at most a few hundred thousand steps).
TIMEOUT = float(os.environ.get("GMSFRIC_FUZZ_TIMEOUT", "20"))
#: Address-space limit of the worker (bytes): a runaway allocation must become a MemoryError.
WORKER_MEMORY = int(float(os.environ.get("GMSFRIC_FUZZ_MEMORY", str(6 * 1024**3))))


def call(name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
    """A node of a generated call: ``REGISTRY[name](*args, **kwargs)`` (arguments evaluated first)."""
    return (CALL, name, args, kwargs)


def _is_call(node: Any) -> bool:
    return isinstance(node, tuple) and len(node) == 4 and isinstance(node[0], str) and node[0] == CALL


def describe(node: Any, depth: int = 0) -> str:
    """A short readable form of a generated call (for failure reports)."""
    if _is_call(node):
        _, name, args, kwargs = node
        parts = [describe(a, depth + 1) for a in args] + [f"{k}={describe(v, depth + 1)}" for k, v in kwargs.items()]
        return f"{name}({', '.join(parts)})"
    if isinstance(node, np.ndarray):
        if node.size <= 4:
            return f"np.array({node.tolist()!r}, dtype={node.dtype})"
        flat = node.ravel()
        return f"<array {node.dtype} {node.shape} [{flat[0]!r}, ..., {flat[-1]!r}]>"
    if isinstance(node, list):
        if len(node) > 6:
            return f"[{', '.join(describe(x, depth + 1) for x in node[:3])}, ... ({len(node)} items)]"
        return "[" + ", ".join(describe(x, depth + 1) for x in node) + "]"
    if isinstance(node, tuple):
        return "(" + ", ".join(describe(x, depth + 1) for x in node) + ("," if len(node) == 1 else "") + ")"
    if isinstance(node, dict):
        return "{" + ", ".join(f"{k!r}: {describe(v, depth + 1)}" for k, v in node.items()) + "}"
    text = repr(node)
    return text if len(text) < 60 else text[:57] + "..."


# ------------------------------------------------------------------------------------------------
# the worker


def _registry() -> dict[str, Any]:
    import gmsfric as g
    from gmsfric import batch, model_io

    def method(obj: Any, name: str, *args: Any, **kwargs: Any) -> Any:
        allowed = {"frequency_response", "simulate", "to_control", "force", "virgin_curve", "static_map", "sample",
                   "with_parameters", "parameters", "model_document", "__call__", "error", "mass"}
        if name not in allowed:
            raise RuntimeError(f"harness: method {name!r} not allowed")
        attr = getattr(obj, name)
        return attr(*args, **kwargs) if callable(attr) else attr

    def document(model: Any, mutations: list[tuple[tuple[Any, ...], Any]]) -> Any:
        """Save ``model``, change the document at ``path``s (a path's last key may be new; a
        path through a missing key is skipped), load it back."""
        doc = model.model_document() if hasattr(model, "model_document") else model_io.model_to_dict(model)
        for path, value in mutations:
            target: Any = doc
            for key in path[:-1]:
                try:
                    target = target[key]
                except (KeyError, IndexError, TypeError):
                    target = None
                    break
            if isinstance(target, dict):
                target[path[-1]] = value
            elif isinstance(target, list) and isinstance(path[-1], int) and -len(target) <= path[-1] < len(target):
                target[path[-1]] = value
        return model_io.model_from_dict(doc)

    def file_round_trip(model: Any, text_edit: tuple[str, str] | None = None, part: Any = None, **save: Any) -> Any:
        """``save_model(model, path, **save)`` then ``load_model(path, part=part)`` through a file
        (optionally editing its text)."""
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "model.json"
            g.save_model(model, path, **save)
            if text_edit is not None:
                path.write_text(path.read_text().replace(*text_edit))
            return g.load_model(path) if part is None else g.load_model(path, part=part)

    from gmsfric import identify, loop

    names = ["Stribeck", "StaticFriction", "GMS", "MaxwellSlip", "LuGre", "Plant", "PID", "Cascade", "PIDDOB", "AxisModel",
             "Effects", "PositionSeries", "Drift", "Heating", "Compliance", "AxisUnits", "Covariance", "simulate_closed_loop",
             "simulate_friction", "save_model", "load_model"]
    reg: dict[str, Any] = {n: getattr(g, n) for n in names}
    reg.update({
        "GMS.from_break_forces": g.GMS.from_break_forces,
        "Plant.from_mass": g.Plant.from_mass,
        "PositionSeries.legendre": g.PositionSeries.legendre,
        "PositionSeries.fourier": g.PositionSeries.fourier,
        "PositionSeries.table": g.PositionSeries.table,
        "batch.simulate_batch": batch.simulate_batch,
        "batch.sweep": batch.sweep,
        "batch.simulate_friction_batch": batch.simulate_friction_batch,
        "model_io.model_from_dict": model_io.model_from_dict,
        "identify.estimate_frf": identify.estimate_frf,
        "identify.fit_static_map": lambda *a, **k: identify.fit_static_map(*a, progress=False, **k),
        "identify.build_virgin_curve": identify.build_virgin_curve,
        "identify.fit_presliding": lambda *a, **k: identify.fit_presliding(*a, progress=False, **k),
        "identify.fit_plant": lambda t, u, y, **k: identify.fit_plant(identify.estimate_frf(t, u, y), **k),
        "loop.AxisData": loop.AxisData,
        "method": method,
        # The harness's own detectors are tested with these.
        "_test.sleep": time.sleep,
        "_test.abort": os.abort,
        "_test.raise": _raise,
        "_test.nan": lambda: np.array([1.0, np.nan]),
        "document": document,
        "file_round_trip": file_round_trip,
    })
    return reg


def _raise(name: str) -> None:
    import builtins

    raise getattr(builtins, name)("raised on purpose")


def _evaluate(node: Any, reg: dict[str, Any]) -> Any:
    if _is_call(node):
        _, name, args, kwargs = node
        fn = reg[name]
        return fn(*(_evaluate(a, reg) for a in args), **{k: _evaluate(v, reg) for k, v in kwargs.items()})
    if isinstance(node, list):
        return [_evaluate(x, reg) for x in node]
    if isinstance(node, tuple):
        return tuple(_evaluate(x, reg) for x in node)
    if isinstance(node, dict):
        return {k: _evaluate(v, reg) for k, v in node.items()}
    return node


def first_nonfinite(value: Any, where: str = "result", depth: int = 0) -> str | None:
    """Where the first NaN or infinity in a result lies (``None``: everything finite)."""
    if depth > 8:
        return None
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fc" and value.size and not np.isfinite(value).all():
            i = int(np.flatnonzero(~np.isfinite(value.ravel()))[0])
            return f"{where}[flat {i}] = {value.ravel()[i]}"
        return None
    if isinstance(value, (float, complex, np.floating, np.complexfloating)):
        return None if np.isfinite(value) else f"{where} = {value}"
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            bad = first_nonfinite(v, f"{where}[{i}]", depth + 1)
            if bad:
                return bad
        return None
    if isinstance(value, dict):
        for k, v in value.items():
            bad = first_nonfinite(v, f"{where}[{k!r}]", depth + 1)
            if bad:
                return bad
        return None
    if hasattr(value, "num") and hasattr(value, "den"):  # a python-control transfer function
        return first_nonfinite(value.num, f"{where}.num", depth + 1) or first_nonfinite(value.den, f"{where}.den", depth + 1)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            bad = first_nonfinite(getattr(value, f.name), f"{where}.{f.name}", depth + 1)
            if bad:
                return bad
        return None
    return None


def _run_one(node: Any, reg: dict[str, Any]) -> tuple[str, str]:
    from gmsfric.errors import GmsfricError

    try:
        result = _evaluate(node, reg)
    except (GmsfricError, MemoryError) as exc:
        return "error", f"{type(exc).__name__}: {exc}"
    except ValueError as exc:
        return "foreign", f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=-3)}"
    except BaseException as exc:  # noqa: BLE001 - classifying everything is the point
        if isinstance(exc, KeyboardInterrupt):
            raise
        kind = "panic" if type(exc).__name__ == "PanicException" else "wrong"
        return kind, f"{type(exc).__module__}.{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=-3)}"
    bad = first_nonfinite(result)
    if bad and _diagnosed(result, bad):
        return "ok", f"{type(result).__name__} (non-finite value with a diagnostic: {bad})"
    return ("nonfinite", bad) if bad else ("ok", type(result).__name__)


def _diagnosed(result: Any, where: str) -> bool:
    """Whether a non-finite value at ``where`` is announced: an identification result whose
    ``diagnostics`` (each also a FitWarning) name that parameter, e.g. an infinite standard error
    of a parameter the data do not determine."""
    match = re.match(r"result\.parameters\['([^']+)'\]", where)
    names = {d.get("parameter") for d in getattr(result, "diagnostics", None) or [] if isinstance(d, dict)}
    return bool(match) and match.group(1) in names


def _read_exact(stream: Any, n: int) -> bytes | None:
    buf = b""
    while len(buf) < n:
        chunk = stream.read(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return buf


def worker_main() -> None:
    """Read length-prefixed pickled calls on stdin, answer ``(outcome, detail)`` on stdout."""
    import resource
    import warnings

    resource.setrlimit(resource.RLIMIT_AS, (WORKER_MEMORY, WORKER_MEMORY))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # an abort leaves no core file behind
    warnings.simplefilter("ignore")
    import matplotlib

    matplotlib.use("Agg")
    reg = _registry()
    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    stdout.write(b"R")
    stdout.flush()
    while True:
        head = _read_exact(stdin, 4)
        if head is None:
            return
        node = pickle.loads(_read_exact(stdin, struct.unpack("<I", head)[0]) or b"")
        answer = pickle.dumps(_run_one(node, reg))
        stdout.write(struct.pack("<I", len(answer)) + answer)
        stdout.flush()


# ------------------------------------------------------------------------------------------------
# the parent


class Harness:
    """Runs generated calls in a worker process, restarting it when it dies or hangs."""

    def __init__(self, timeout: float = TIMEOUT) -> None:
        self.timeout = timeout
        self.proc: subprocess.Popen[bytes] | None = None
        self.counts: Counter[str] = Counter()
        self.examples: dict[str, list[str]] = {}
        #: Clean errors by message shape (numbers dropped): shows what the generated calls reach.
        self.errors: Counter[str] = Counter()
        self._stderr: Any = None

    def _start(self) -> None:
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", RAYON_NUM_THREADS="2", MPLBACKEND="Agg")
        self._stderr = tempfile.TemporaryFile()
        self.proc = subprocess.Popen([sys.executable, __file__, "--worker"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self._stderr, env=env)
        ready = self._read(60.0, 1)
        if ready != b"R":
            raise RuntimeError(f"the fuzz worker did not start: {self._stderr_tail()}")

    def _read(self, timeout: float, n: int) -> bytes | None:
        assert self.proc is not None and self.proc.stdout is not None
        deadline = time.monotonic() + timeout
        buf = b""
        fd = self.proc.stdout.fileno()
        while len(buf) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError
            ready, _, _ = select.select([fd], [], [], left)
            if not ready:
                raise TimeoutError
            chunk = os.read(fd, n - len(buf))
            if not chunk:
                return None
            buf += chunk
        return buf

    def _stderr_tail(self) -> str:
        if self._stderr is None:
            return ""
        self._stderr.seek(0)
        text = self._stderr.read().decode("utf-8", "replace")
        return "\n".join(text.strip().splitlines()[-6:])

    def _kill(self) -> None:
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait()
            self.proc = None

    def close(self) -> None:
        if self.proc is not None and self.proc.stdin is not None:
            try:
                self.proc.stdin.close()
                self.proc.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                pass
        self._kill()

    def run(self, node: Any) -> tuple[str, str]:
        """Outcome and detail of one generated call (counted)."""
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        assert self.proc is not None and self.proc.stdin is not None
        payload = pickle.dumps(node)
        outcome: tuple[str, str] | None = None
        try:
            self.proc.stdin.write(struct.pack("<I", len(payload)) + payload)
            self.proc.stdin.flush()
            head = self._read(self.timeout, 4)
            body = None if head is None else self._read(self.timeout, struct.unpack("<I", head)[0])
            if body is not None:
                outcome = pickle.loads(body)
        except TimeoutError:
            self._kill()
            outcome = ("hang", f"no answer within {self.timeout} s")
        except BrokenPipeError:
            pass
        if outcome is None:
            code = self.proc.wait()
            name = signal.Signals(-code).name if code < 0 else f"exit code {code}"
            tail = self._stderr_tail()
            outcome = ("panic" if "panicked at" in tail else "died", f"worker died ({name}): {tail}")
            self.counts[f"died by {name}"] += 1
            self.proc = None
        self.counts["calls"] += 1
        self.counts[outcome[0]] += 1
        if outcome[0] == "error":
            self.errors[re.sub(r"-?\d[\d.]*(e[-+]?\d+)?", "#", outcome[1])[:90]] += 1
        if outcome[0] in FAILURES:
            self.examples.setdefault(outcome[0], []).append(f"{describe(node)}\n    -> {outcome[1]}")
        return outcome


# ------------------------------------------------------------------------------------------------
# strategies

@dataclasses.dataclass(frozen=True)
class Num:
    """A kind of number: ``moderate`` values (most draws, so that calls get deep) and ``wide``
    ones (subnormal to 1e308: valid but extreme)."""

    moderate: Any
    wide: Any


@dataclasses.dataclass(frozen=True)
class Profile:
    """How hostile one generated call is: each parameter is hostile (any type, nan, inf, wrong
    shape) with probability ``hostile`` and, when not, extreme with probability ``extreme``."""

    hostile: float
    extreme: float


def _strategies() -> dict[str, Any]:
    """Build the hypothesis strategies (imported lazily: the worker does not need hypothesis)."""
    from hypothesis import strategies as st

    def mant_exp(lo: int, hi: int) -> Any:
        return st.builds(lambda m, e: float(m * 10.0**e), st.floats(1.0, 9.99), st.integers(lo, hi))

    specials_pos = st.sampled_from([5e-324, 1e-310, 2.2250738585072014e-308, 1e-200, 1e-30, 1e-12, 1e-9, 1e-6, 1e6, 1e12, 1e30,
                                    1e100, 1e200, 1e300, 1.7976931348623157e308])
    wide_pos = st.one_of(mant_exp(-320, 307), specials_pos)
    pos = Num(mant_exp(-4, 4), wide_pos)
    nonneg = Num(st.one_of(mant_exp(-4, 4), st.just(0.0)), st.one_of(wide_pos, st.sampled_from([0.0, -0.0])))
    real = Num(st.one_of(mant_exp(-4, 4), mant_exp(-4, 4).map(lambda x: -x), st.just(0.0)),
               st.one_of(wide_pos, wide_pos.map(lambda x: -x), st.sampled_from([0.0, -0.0])))
    zero_or_pos = Num(st.one_of(st.just(0.0), mant_exp(-6, -1)), st.one_of(st.just(0.0), wide_pos))
    dts = Num(st.sampled_from([1e-4, 1e-3, 2.5e-4, 1e-5]), st.one_of(st.sampled_from([1e-9, 5e-324, 1e-300, 1.0, 1e6, 1e300]), wide_pos))
    delays = Num(st.one_of(st.just(0.0), mant_exp(-5, -2)), st.one_of(st.sampled_from([0.0, 1e3, 1e6, 1e10, 1e20, 1e300]), wide_pos))
    counts = Num(st.integers(1, 5), st.integers(6, 10**6))
    hostile_scalar = st.one_of(
        st.sampled_from([math.nan, math.inf, -math.inf, -1.0, -0.0, 0.0, 5e-324, 1.7976931348623157e308, -1.7976931348623157e308,
                         10**400, -(10**400), 2**64, 2**63, -(2**63), True, False, None, "1", "abc", "", "nan", [1.0], [],
                         (1, 2, 3), (1.0, 2.0), 1j, {}, b"1"]),
        st.builds(np.float32, st.floats(-3e38, 3e38)),
        st.builds(np.int64, st.integers(-(2**63), 2**63 - 1)),
        st.floats(),
        st.builds(lambda n: np.ones((n, 2)), st.integers(0, 3)),
    )

    def chance(draw: Any, p: float) -> bool:
        return p > 0 and draw(st.integers(0, 999)) < p * 1000

    def value(draw: Any, base: Any, prof: Profile) -> Any:
        """A valid-typed value of ``base`` (a Num: moderate or, sometimes, extreme)."""
        if isinstance(base, Num):
            return draw(base.wide if chance(draw, prof.extreme) else base.moderate)
        return draw(base)

    @st.composite
    def param(draw: Any, base: Any, prof: Profile) -> Any:
        if chance(draw, prof.hostile):
            return draw(hostile_scalar)
        return value(draw, base, prof)

    def lists(base: Any, prof: Profile, n: int) -> Any:
        return st.lists(param(base, prof), min_size=n, max_size=n)

    @st.composite
    def array(draw: Any, n: int, base: Any, prof: Profile, rows: int = 0) -> Any:
        if chance(draw, prof.hostile * 0.3):
            return draw(st.one_of(
                hostile_scalar,
                st.just(np.zeros(0)),
                st.just(np.zeros(n + 1)),
                st.just(np.zeros((2, 2, n))),
                st.just(np.array(["a"] * n)),
                st.just(np.zeros(n, dtype=complex)),
                st.just(np.ones(n, dtype=bool)),
                st.just(np.arange(n, dtype=np.int64)),
                st.just([0.0] * (n - 1) + [None]),
                st.just(np.zeros(2 * n)[::2]),
                st.just(np.zeros((rows + 1, n))),
            ))
        style = draw(st.sampled_from(["sine", "sine", "const", "ramp", "random" if n <= 400 else "sine", "zeros"]))
        amp = value(draw, base, prof)
        k = np.arange(n, dtype=float)
        with np.errstate(all="ignore"):
            if style == "sine":
                values = amp * np.sin(2 * np.pi * k / max(n, 2) * draw(st.floats(0.1, 5.0)))
            elif style == "const":
                values = np.full(n, amp)
            elif style == "ramp":
                values = amp * k / max(n - 1, 1)
            elif style == "zeros":
                values = np.zeros(n)
            else:
                values = np.array([value(draw, base, prof) for _ in range(n)], dtype=float)
            values = np.asarray(values, dtype=float)
            if n and chance(draw, prof.hostile * 0.4):
                values = values.copy()
                values[draw(st.integers(0, n - 1))] = draw(st.sampled_from([math.nan, math.inf, -math.inf, 1.7976931348623157e308, 5e-324]))
            if rows > 1 and draw(st.booleans()):
                values = np.tile(values, (rows, 1)) * np.linspace(1.0, 1.5, rows)[:, None]
        return values

    @st.composite
    def stribeck(draw: Any, prof: Profile) -> Any:
        fc = draw(param(nonneg, prof))
        fs = draw(st.one_of(param(nonneg, prof), st.just(fc)))
        delta = draw(param(Num(st.sampled_from([1.0, 2.0, 0.5]), pos.wide), prof))
        return call("Stribeck", fc, fs, draw(param(pos, prof)), delta)

    def weights(draw: Any, n: int) -> list[float]:
        raw = draw(st.lists(st.floats(0.01, 1.0), min_size=n, max_size=n))
        total = sum(raw)
        return [w / total for w in raw]

    @st.composite
    def friction(draw: Any, prof: Profile, kinds: tuple[str, ...] = ("static", "gms", "gms_w", "maxwell", "lugre")) -> Any:
        kind = draw(st.sampled_from(kinds))
        if kind == "static":
            return call("StaticFriction", draw(stribeck(prof)), draw(param(nonneg, prof)), draw(param(real, prof)),
                        draw(param(zero_or_pos, prof)))
        if kind in ("gms", "gms_w"):
            n = draw(st.integers(1, 5))
            k = draw(lists(pos, prof, n))
            law = draw(param(st.sampled_from(["time", "displacement"]), prof))
            if kind == "gms":
                return call("GMS", draw(stribeck(prof)), k, draw(param(st.just(weights(draw, n)), prof)), draw(param(pos, prof)),
                            draw(param(nonneg, prof)), law)
            return call("GMS.from_break_forces", k, draw(lists(nonneg, prof, n)), draw(param(pos, prof)),
                        stribeck=draw(st.one_of(st.none(), stribeck(prof))), sigma=draw(param(nonneg, prof)), slip_law=law,
                        scale=draw(param(st.sampled_from(["stribeck", "sum"]), prof)))
        if kind == "maxwell":
            n = draw(st.integers(1, 5))
            return call("MaxwellSlip", draw(lists(pos, prof, n)), draw(lists(nonneg, prof, n)), draw(param(nonneg, prof)))
        return call("LuGre", draw(stribeck(prof)), draw(param(pos, prof)), draw(param(nonneg, prof)), draw(param(nonneg, prof)))

    @st.composite
    def plant(draw: Any, prof: Profile) -> Any:
        delay = draw(param(delays, prof))
        if draw(st.integers(0, 4)) == 0:
            return call("Plant.from_mass", draw(param(pos, prof)), draw(param(nonneg, prof)), draw(param(nonneg, prof)), delay,
                        draw(param(pos, prof)))
        return call("Plant", draw(param(pos, prof)), draw(param(nonneg, prof)), draw(param(nonneg, prof)), delay, draw(param(pos, prof)))

    @st.composite
    def pid(draw: Any, prof: Profile) -> Any:
        args = [draw(param(real, prof)) for _ in range(3)] + [draw(param(zero_or_pos, prof))]
        if draw(st.booleans()):
            lo, hi = draw(param(real, prof)), draw(param(real, prof))
            if isinstance(lo, float) and isinstance(hi, float) and lo > hi:
                lo, hi = hi, lo
            args += [lo, hi]
        return call("PID", *args)

    @st.composite
    def controller(draw: Any, prof: Profile, allow_none: bool = True) -> Any:
        kind = draw(st.sampled_from(["none", "pid", "pid", "cascade", "dob"] if allow_none else ["pid", "pid", "cascade", "dob"]))
        if kind == "none":
            return None
        if kind == "pid":
            return draw(pid(prof))
        if kind == "cascade":
            return call("Cascade", draw(param(real, prof)), draw(param(real, prof)))
        return call("PIDDOB", draw(pid(prof)), draw(plant(prof)), draw(param(pos, prof)))

    @st.composite
    def series(draw: Any, prof: Profile) -> Any:
        kind = draw(st.sampled_from(["legendre", "fourier", "table"]))
        if kind == "legendre":
            return call("PositionSeries.legendre", draw(param(real, prof)), draw(param(real, prof)),
                        draw(st.lists(param(real, prof), min_size=1, max_size=5)))
        if kind == "fourier":
            n_p, n_h = draw(st.integers(1, 2)), draw(param(st.integers(1, 3), prof))
            n_coef = 2 * n_p * (n_h if isinstance(n_h, int) and not isinstance(n_h, bool) and 0 < n_h < 10 else 1)
            return call("PositionSeries.fourier", draw(lists(pos, prof, n_p)), n_h, draw(lists(real, prof, n_coef)))
        n = draw(st.integers(2, 6))
        q0, dq = value(draw, real, prof), value(draw, pos, prof)
        return call("PositionSeries.table", draw(param(st.just([q0 + i * dq for i in range(n)]), prof)), draw(lists(real, prof, n)))

    @st.composite
    def effects(draw: Any, prof: Profile, level_shifts: bool) -> Any:
        kw: dict[str, Any] = {}
        if level_shifts and draw(st.booleans()):
            kw["asymmetry"] = draw(param(st.tuples(real.moderate, real.moderate), prof))
        if draw(st.booleans()):
            kw["position_force"] = draw(series(prof))
        if level_shifts and draw(st.booleans()):
            kw["position_friction"] = draw(series(prof))
        if level_shifts and draw(st.booleans()):
            kw["drift"] = call("Drift", draw(param(st.sampled_from(["linear", "exponential"]), prof)), draw(param(pos, prof)),
                               draw(param(real, prof)), draw(param(real, prof)))
        if level_shifts and draw(st.booleans()):
            kw["heating"] = call("Heating", draw(param(pos, prof)), draw(param(real, prof)), draw(param(real, prof)))
        if draw(st.booleans()):
            n = draw(st.integers(1, 3))
            kw["blocks"] = call("MaxwellSlip", draw(lists(pos, prof, n)), draw(lists(nonneg, prof, n)))
        if draw(st.booleans()):
            kw["compliance"] = call("Compliance", draw(param(pos, prof)), draw(param(pos, prof)), draw(param(nonneg, prof)))
        return call("Effects", **kw)

    @st.composite
    def axis_model(draw: Any, prof: Profile) -> Any:
        fr = draw(st.one_of(st.none(), friction(prof)))
        level_shifts = isinstance(fr, tuple) and fr[1] == "StaticFriction"
        if prof.hostile > 0 and draw(st.integers(0, 9)) == 0:
            level_shifts = True  # level shifts on a model that cannot take them: must be refused
        kw: dict[str, Any] = {}
        if draw(st.integers(0, 3)) == 0:
            kw["units"] = call("AxisUnits", draw(param(st.sampled_from(["linear", "rotary"]), prof)),
                               draw(param(st.sampled_from(["V", "A"]), prof)))
        if draw(st.integers(0, 3)) == 0:
            names = draw(st.lists(st.sampled_from(["plant.a", "plant.b", "plant.c", "plant.delay", "friction.stribeck.fc", "friction.sigma",
                                                   "friction.k.0", "effects.asymmetry.0", "nonsense.path"]), min_size=1, max_size=3, unique=True))
            diag = [value(draw, nonneg, prof) for _ in names]
            matrix = draw(param(st.just(np.diag(diag)), prof))
            kw["covariance"] = call("Covariance", tuple(names), matrix)
        return call("AxisModel", draw(plant(prof)), fr, draw(effects(prof, level_shifts)), **kw)

    profiles = st.builds(Profile, st.sampled_from([0.0, 0.0, 0.02, 0.08, 0.25]), st.sampled_from([0.0, 0.05, 0.2, 0.6]))
    lengths = st.one_of(st.integers(1, 40), st.integers(41, 400), st.sampled_from([2, 3, 4096, 4097, 32768, 70_000]))

    @st.composite
    def run_options(draw: Any, n: int, prof: Profile, rows: int = 0) -> dict[str, Any]:
        opts: dict[str, Any] = {}
        for name in ("feedforward", "input_disturbance", "load_force", "measurement_noise"):
            if draw(st.integers(0, 3)) == 0:
                opts[name] = draw(array(n, real, prof, rows))
        if draw(st.integers(0, 3)) == 0:
            opts["quantization"] = draw(param(Num(st.sampled_from([0.0, 1e-6, 1e-8]), zero_or_pos.wide), prof))
        if draw(st.integers(0, 3)) == 0:
            opts["drive_limit"] = draw(st.one_of(param(pos, prof), st.tuples(param(real, prof), param(real, prof)), st.just(None),
                                                 st.just((1, 2, 3)) if prof.hostile else st.just(10.0)))
        if draw(st.integers(0, 4)) == 0:
            opts["initial_position"] = draw(param(real, prof))
        if draw(st.integers(0, 4)) == 0:
            opts["initial_velocity"] = draw(param(real, prof))
        if draw(st.integers(0, 2)) == 0:
            outputs = ["position", "velocity", "measured", "command", "friction", "error"]
            opts["record"] = draw(st.one_of(st.lists(st.sampled_from(outputs), min_size=0, max_size=6, unique=True),
                                            st.sampled_from(outputs), param(st.just(["position"]), prof)))
        if draw(st.integers(0, 2)) == 0:
            opts["every"] = draw(param(counts, prof))
        if prof.hostile and draw(st.integers(0, 30)) == 0:
            opts["no_such_option"] = 1.0
        return opts

    def inner(draw: Any, prof: Profile) -> Profile:
        """The profile of the objects a call is given: half the time clean (hostile values then
        reach the call's own arguments, deep in the work, instead of stopping at a constructor)."""
        return prof if draw(st.booleans()) else Profile(0.0, prof.extreme)

    @st.composite
    def closed_loop(draw: Any) -> Any:
        prof = draw(profiles)
        models = inner(draw, prof)
        n = draw(lengths)
        ctrl = draw(controller(models))
        as_axis = draw(st.integers(0, 2)) == 0
        p = draw(axis_model(models)) if as_axis else draw(plant(models))
        fr = None if as_axis else draw(st.one_of(st.none(), friction(models)))
        ref = draw(array(n, real, prof)) if ctrl is not None or draw(st.booleans()) else None
        opts = draw(run_options(n, prof))
        if ctrl is None and "feedforward" not in opts:
            opts["feedforward"] = draw(array(n, real, prof))
        if as_axis and draw(st.integers(0, 2)) == 0:
            command = opts.pop("feedforward", None)
            return call("method", p, "simulate", draw(param(dts, prof)), reference=ref, controller=ctrl, command=command, **opts)
        return call("simulate_closed_loop", p, fr, ctrl, ref, draw(param(dts, prof)), **opts)

    @st.composite
    def friction_run(draw: Any) -> Any:
        prof = draw(profiles)
        n = draw(st.integers(2, 300))
        model = draw(friction(inner(draw, prof)))
        steps = draw(array(n, Num(st.sampled_from([1e-4, 1e-3, 1e-2]), pos.wide), prof))
        t = steps
        if isinstance(steps, np.ndarray) and steps.dtype.kind == "f" and steps.ndim == 1:
            with np.errstate(all="ignore"):
                t = np.cumsum(np.abs(steps) + (steps == 0))
        motion = Num(st.sampled_from([1e-6, 1e-5, 1e-3, 0.1]), real.wide)
        if draw(st.booleans()):
            return call("simulate_friction", model, t, draw(array(n, motion, prof)))
        return call("simulate_friction", model, t, velocity=draw(array(n, motion, prof)))

    @st.composite
    def model_calls(draw: Any) -> Any:
        prof = draw(profiles)
        models = inner(draw, prof)
        kind = draw(st.sampled_from(["static_force", "stribeck", "virgin", "freq", "freq_dt", "plant_sim", "to_control", "pid_freq",
                                     "static_map", "mass"]))
        n = draw(st.integers(1, 50))
        if kind == "static_force":
            return call("method", draw(friction(models, ("static",))), "force", draw(array(n, real, prof)))
        if kind == "stribeck":
            return call("method", draw(stribeck(models)), "__call__", draw(array(n, real, prof)))
        if kind == "virgin":
            return call("method", draw(friction(models, ("gms", "gms_w", "maxwell"))), "virgin_curve", draw(array(n, real, prof)))
        if kind == "static_map":
            return call("method", draw(friction(models, ("gms", "gms_w"))), "static_map")
        if kind == "mass":
            return call("method", draw(plant(models)), "mass")
        if kind in ("freq", "freq_dt"):
            f = draw(array(n, nonneg, prof))
            if kind == "freq":
                return call("method", draw(plant(models)), "frequency_response", f)
            return call("method", draw(plant(models)), "frequency_response", f, draw(param(dts, prof)))
        if kind == "plant_sim":
            return call("method", draw(plant(models)), "simulate", draw(array(n, real, prof)), draw(param(dts, prof)))
        if kind == "pid_freq":
            return call("method", draw(pid(models)), "frequency_response", draw(array(n, nonneg, prof)), draw(param(dts, prof)))
        which = draw(st.sampled_from(["pade", "dt", "pid", "pid_dt"]))
        if which == "pade":
            return call("method", draw(plant(models)), "to_control", pade_order=draw(param(counts, prof)))
        if which == "dt":
            return call("method", draw(plant(models)), "to_control", dt=draw(param(dts, prof)))
        if which == "pid":
            return call("method", draw(pid(models)), "to_control")
        return call("method", draw(pid(models)), "to_control", dt=draw(param(dts, prof)))

    @st.composite
    def batch_calls(draw: Any) -> Any:
        prof = draw(profiles)
        models = inner(draw, prof)
        n = draw(st.integers(1, 200))
        runs = draw(st.integers(1, 4))
        threads = draw(st.one_of(st.none(), st.sampled_from([1, 2]), param(st.just(2), Profile(max(prof.hostile, 0.1), 0.0))))
        kind = draw(st.sampled_from(["batch", "batch", "sweep", "friction"]))
        if kind == "friction":
            frictions = draw(st.lists(friction(models), min_size=0 if prof.hostile else 1, max_size=runs))
            with np.errstate(all="ignore"):
                t = np.cumsum(np.full(n, value(draw, pos, prof)))
            return call("batch.simulate_friction_batch", frictions, draw(param(st.just(t), prof)),
                        draw(array(n, Num(st.sampled_from([1e-6, 1e-3]), real.wide), prof, len(frictions))), threads=threads)
        ctrl = draw(controller(models))
        ref = draw(array(n, real, prof, runs)) if ctrl is not None or draw(st.booleans()) else None
        opts = draw(run_options(n, prof, runs))
        if ctrl is None and "feedforward" not in opts:
            opts["feedforward"] = draw(array(n, real, prof, runs))
        if kind == "sweep":
            key = draw(st.sampled_from(["plant.delay", "plant.b", "controller.kp", "friction.sigma", "friction.stribeck.fc", "plant",
                                        "nonsense.x", "controller.nope"]))
            values = draw(st.lists(param(nonneg, prof), min_size=0 if prof.hostile else 1, max_size=runs))
            fr = draw(st.one_of(st.none(), friction(models)))
            return call("batch.sweep", draw(plant(models)), fr, ctrl, ref, draw(param(dts, prof)), vary={key: values}, threads=threads, **opts)
        plants = draw(st.one_of(plant(models), st.lists(st.one_of(plant(models), axis_model(models)), min_size=runs, max_size=runs)))
        has_axis = isinstance(plants, list) and any(p[1] == "AxisModel" for p in plants)
        frictions = None if has_axis else draw(st.one_of(st.none(), friction(models),
                                                         st.lists(st.one_of(st.none(), friction(models)), min_size=runs, max_size=runs)))
        return call("batch.simulate_batch", plants, frictions, ctrl, ref, draw(param(dts, prof)), threads=threads,
                    progress=draw(st.sampled_from([None, False])), **opts)

    mutation_values = st.one_of(hostile_scalar, real.wide, st.just({"value": 1.0, "unit": "furlong"}), st.just({"value": "x", "unit": "m"}),
                                st.just({"value": 1e308, "unit": "mm"}), st.just({"value": 1e308, "unit": "km"}), st.just({"unit": "N"}),
                                st.just([]), st.just(["x"]), st.just({}), st.just([1e308, 1e308]))
    doc_paths = st.one_of(
        st.tuples(st.sampled_from(["schema", "kind", "axis", "parameters", "options", "covariance", "provenance", "gmsfric_version", "models"])),
        st.tuples(st.just("parameters"), st.sampled_from(["a", "b", "c", "delay", "force_gain", "fc", "fs", "vs", "delta", "sigma", "k", "w",
                                                          "alpha", "sigma0", "plant.a", "plant.delay", "friction.fc", "friction.k",
                                                          "effects.blocks.k", "effects.compliance.fn_hz", "extra"])),
        st.tuples(st.just("parameters"), st.sampled_from(["a", "fc", "k", "plant.a", "plant.delay", "friction.fc", "vs", "delay"]),
                  st.sampled_from(["value", "unit"])),
        st.tuples(st.just("options"), st.sampled_from(["slip_law", "friction", "command_unit", "effects.drift", "effects.position_force"])),
        st.tuples(st.just("covariance"), st.sampled_from(["names", "units", "matrix"])),
    )

    @st.composite
    def model_files(draw: Any) -> Any:
        prof = draw(profiles)
        models = inner(draw, prof)
        model = draw(st.one_of(friction(models), plant(models), axis_model(models)))
        kind = draw(st.sampled_from(["doc", "doc", "file", "edit"]))
        if kind == "doc":
            return call("document", model, draw(st.lists(st.tuples(doc_paths, mutation_values), min_size=0, max_size=3)))
        if kind == "file":
            save: dict[str, Any] = {}
            if draw(st.booleans()):
                save["rotary"] = draw(param(st.booleans(), prof))
            if draw(st.booleans()):
                save["drive"] = draw(param(st.sampled_from(["V", "A"]), prof))
            if draw(st.booleans()):
                save["provenance"] = draw(param(st.just({"command": "fuzz", "files": ["a.csv"]}), prof))
            if draw(st.integers(0, 3)) == 0:
                # A bundle of named models, read back whole or by part.
                other = draw(st.one_of(friction(models), plant(models)))
                names = draw(st.one_of(st.just(["plant", "friction"]), st.just(["", "x"]), st.just(["a", "a "])))
                part = draw(st.one_of(st.none(), st.sampled_from(names), param(st.just("missing"), prof)))
                return call("file_round_trip", {names[0]: model, names[1]: other}, part=part, **save)
            return call("file_round_trip", model, **save)
        edit = draw(st.sampled_from([("\"value\": ", "\"value\": 1e999 + "), ("1", "NaN"), ("{", "["), ("\"m\"", "\"km\""),
                                     ("\"N\"", "\"lbf\""), ("e", "E"), ("gmsfric.model/1", "gmsfric.model/2"), ("0", "-"),
                                     ("\"value\": ", "\"value\": 1e300"), ("\"s\"", "\"ms\"")]))
        return call("file_round_trip", model, edit)

    @st.composite
    def axis_calls(draw: Any) -> Any:
        prof = draw(profiles)
        m = draw(axis_model(inner(draw, prof)))
        kind = draw(st.sampled_from(["parameters", "with", "sample", "doc"]))
        if kind == "parameters":
            return call("method", m, "parameters")
        if kind == "doc":
            return call("method", m, "model_document")
        if kind == "with":
            path = draw(st.sampled_from(["plant.a", "plant.delay", "friction.stribeck.fc", "x", "effects.blocks.k.0", "plant.a.b", 1, None]))
            return call("method", m, "with_parameters", draw(param(st.just({path: draw(param(real, prof))}), prof)))
        # The work grows with n (each draw is a validated model): keep valid counts small.
        n = draw(param(Num(st.integers(1, 5), st.integers(6, 2000)), prof))
        return call("method", m, "sample", n, seed=draw(param(st.integers(0, 10), prof)))

    @st.composite
    def measured_calls(draw: Any) -> Any:
        """Identification and the loop's data on measured signals: a sine record at moderate or
        extreme scales (its samples sometimes replaced by hostile arrays)."""
        prof = draw(profiles)
        n = draw(st.integers(2, 400))
        scale = draw(param(Num(st.sampled_from([1e-6, 1e-3, 1.0, 1e3]), real.wide), prof))
        dt = draw(param(dts, prof))
        with np.errstate(all="ignore"):
            try:
                t = np.arange(n) * float(dt)
                wave = float(scale) * np.sin(np.linspace(0.0, 12.0, n))
            except (TypeError, ValueError, OverflowError):
                t, wave = np.arange(n) * 1e-3, np.sin(np.linspace(0.0, 12.0, n))
        record = Num(st.just(0.0), real.wide)
        t = t if not chance(draw, prof.hostile) else draw(array(n, record, prof))
        x = wave if not chance(draw, prof.hostile) else draw(array(n, record, prof))
        f = np.cos(np.linspace(0.0, 12.0, n)) if not chance(draw, prof.hostile) else draw(array(n, record, prof))
        kind = draw(st.sampled_from(["frf", "plant", "static_map", "virgin", "presliding", "axis_data"]))
        if kind == "frf":
            return call("identify.estimate_frf", t, f, x)
        if kind == "plant":
            return call("identify.fit_plant", t, f, x, max_delay=draw(param(Num(st.just(0.01), real.wide), prof)),
                        fmax=draw(param(Num(st.just(100.0), real.wide), prof)))
        if kind == "static_map":
            return call("identify.fit_static_map", x, f)
        if kind == "virgin":
            return call("identify.build_virgin_curve", t, x, f)
        if kind == "presliding":
            return call("identify.fit_presliding", t, x, f, max_blocks=draw(st.integers(1, 3)))
        return call("loop.AxisData", t, x, f, rotary=draw(param(st.booleans(), prof)))

    return {
        "measured": measured_calls(),
        "closed_loop": closed_loop(),
        "friction": friction_run(),
        "models": model_calls(),
        "batch": batch_calls(),
        "model_files": model_files(),
        "axis": axis_calls(),
    }


_FAMILIES: dict[str, Any] | None = None


def families() -> dict[str, Any]:
    """The strategies by family: ``closed_loop``, ``friction``, ``models``, ``batch``,
    ``model_files``, ``axis``."""
    global _FAMILIES
    if _FAMILIES is None:
        _FAMILIES = _strategies()
    return _FAMILIES


def api_call() -> Any:
    """One strategy over every family."""
    from hypothesis import strategies as st

    return st.one_of(*families().values())


if __name__ == "__main__" and sys.argv[1:] == ["--worker"]:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    worker_main()
