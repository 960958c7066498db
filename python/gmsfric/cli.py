"""The ``gmsfric`` command line: one runner for every command.

Each subcommand lives in its own module exposing ``register(subparsers)``: the module adds its
parser, declares its input files and outputs with :func:`declare_files` and sets ``func``, called
as ``func(args, run)`` with a :class:`Run` and returning an exit code.  Adding a command = adding
its name and module to ``COMMANDS``.  Only the module of the command being run is imported (the
command modules import scipy, which takes seconds); help and unknown commands import them all.

The runner, not the commands, owns

* errors: every failure is one line on stderr, ``gmsfric CMD: error: ...``, exit code 2 (1 when a
  fit failed, :class:`~gmsfric.errors.IdentificationError`; 130 on Ctrl-C); tracebacks only with
  ``--debug``;
* files: declared inputs must be readable regular files (text ones UTF-8), outputs must go into
  an existing directory, must not be a directory, and must not be one of the inputs; all of this is
  checked before any work, and every output is written atomically (:meth:`Run.write_json`,
  :meth:`Run.write_figures`);
* ``-q/--quiet`` and ``-v/--verbose``, mapped to ``logging`` levels of the ``gmsfric`` logger
  (``-q`` also turns progress off).

Argument types (:func:`positive_int`, :func:`fraction`, ...) refuse bad numbers at parse time.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import importlib
import logging
import math
import os
import shlex
import sys
import tempfile
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator, Mapping, Sequence

from .errors import DataError, GmsfricError, IdentificationError, InvalidInputError

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .results import Result

COMMANDS = {
    "identify": "gmsfric.identify.cli",
    "paper": "gmsfric.identify.cli",
    "demo": "gmsfric.demo",
    "loop": "gmsfric.loop.cli",
    "glitch": "gmsfric.glitch.cli",
}

log = logging.getLogger("gmsfric")


# ------------------------------------------------------------------------------------------
# argument types: refuse bad numbers while parsing (argparse turns the message into a usage error)


def _number(text: str, kind: Callable[[str], Any]) -> Any:
    try:
        return kind(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if kind is int else 'a number'}") from None


def positive_int(text: str) -> int:
    """An integer >= 1."""
    v = _number(text, int)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {v}")
    return v  # type: ignore[no-any-return]


def non_negative_int(text: str) -> int:
    """An integer >= 0."""
    v = _number(text, int)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {v}")
    return v  # type: ignore[no-any-return]


def int_at_least(low: int) -> Callable[[str], int]:
    """An integer >= ``low``."""

    def parse(text: str) -> int:
        v = _number(text, int)
        if v < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {v}")
        return v  # type: ignore[no-any-return]

    return parse


def finite_float(text: str) -> float:
    """A finite number."""
    v = float(_number(text, float))
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return v


def positive_float(text: str) -> float:
    """A finite number > 0."""
    v = finite_float(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {v:g}")
    return v


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    v = finite_float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {v:g}")
    return v


def positive_or_inf(text: str) -> float:
    """A number > 0, ``inf`` allowed (an open upper bound); never NaN."""
    v = float(_number(text, float))
    if math.isnan(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0 (or inf), got {text!r}")
    return v


def fraction(text: str) -> float:
    """A number strictly between 0 and 1."""
    v = finite_float(text)
    if not 0.0 < v < 1.0:
        raise argparse.ArgumentTypeError(f"must be between 0 and 1 (exclusive), got {v:g}")
    return v


# ------------------------------------------------------------------------------------------
# parsers


class UsageError(Exception):
    """A command line that argparse cannot accept."""

    def __init__(self, prog: str, message: str) -> None:
        super().__init__(message)
        self.prog, self.message = prog, message


class ArgumentParser(argparse.ArgumentParser):
    """argparse without its exit: errors become :class:`UsageError` (one line from the runner)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(self.prog, message)


#: Unit arguments of the Python API, named on the command line by their flags.
UNIT_ARGS = ("time_unit", "position_unit", "force_unit", "velocity_unit", "input_unit", "output_unit", "force_gain_unit")


@contextlib.contextmanager
def units_as_flags() -> Iterator[None]:
    """Errors of the Python API name its unit arguments (`` `force_unit` ``); on the command
    line they name the flags (``--force-unit``)."""
    try:
        yield
    except InvalidInputError as exc:
        text = str(exc)
        for name in UNIT_ARGS:
            text = text.replace(f"`{name}`", "--" + name.replace("_", "-"))
        if text == str(exc):
            raise
        raise type(exc)(text) from None


@dataclass(frozen=True)
class Files:
    """Argument names (``dest``) of a command's input files, output files and output folders;
    ``stdout`` lists outputs for which ``-`` means standard output."""

    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    output_dirs: tuple[str, ...] = ()
    stdout: tuple[str, ...] = ()


def declare_files(parser: argparse.ArgumentParser, *, inputs: Sequence[str] = (), outputs: Sequence[str] = (),
                  output_dirs: Sequence[str] = (), stdout: Sequence[str] = ()) -> None:
    """Declare which arguments of ``parser`` are input files, output files and output folders,
    so the runner checks them before any work (see the module docstring)."""
    parser.set_defaults(_files=Files(tuple(inputs), tuple(outputs), tuple(output_dirs), tuple(stdout)))


def _subparsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    out = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                out.append(sub)
                out.extend(_subparsers(sub))
    return out


def _add_common(p: argparse.ArgumentParser, default: Any) -> None:
    g = p.add_argument_group("output and diagnostics")
    g.add_argument("-q", "--quiet", action="store_true", default=default, help="no progress and no log below warnings (the result is still printed)")
    g.add_argument("-v", "--verbose", action="store_true", default=default, help="more detail (debug log)")
    g.add_argument("--debug", action="store_true", default=default, help="show the Python traceback of an error")


def _command_modules(argv: Sequence[str]) -> list[str]:
    """The modules to import for ``argv``: the one of its command, none for ``--version`` alone,
    all of them to list the commands (help, no command, an unknown one)."""
    # the options before a command are all flags, so its name is the first word without a dash
    # (argparse refuses a command after "--")
    before = argv[: argv.index("--")] if "--" in argv else argv
    command = next((a for a in before if not a.startswith("-")), None)
    if command in COMMANDS:
        return [COMMANDS[command]]
    if command is None and "--version" in argv and not {"-h", "--help"} & set(argv):
        return []
    return list(dict.fromkeys(COMMANDS.values()))


def build_parser(argv: Sequence[str] = ()) -> ArgumentParser:
    """The ``gmsfric`` parser with the command named in ``argv``, or with every command of
    ``COMMANDS`` when ``argv`` names none of them."""
    parser = ArgumentParser(prog="gmsfric", description="Friction identification and fast simulation of precision servo axes.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    _add_common(parser, False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=ArgumentParser)
    for name in _command_modules(list(argv)):
        importlib.import_module(name).register(sub)
    for p in _subparsers(parser):
        # the same options after the command; SUPPRESS keeps a value given before it
        _add_common(p, argparse.SUPPRESS)
        p.set_defaults(_prog=p.prog)
    return parser


# ------------------------------------------------------------------------------------------
# the run context


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


@dataclass
class Run:
    """What a command gets from the runner besides its arguments: the checked inputs, the
    command line, provenance, and the only way to write outputs (atomically, never over an input)."""

    command: str
    argv: list[str]
    inputs: list[Path] = field(default_factory=list)
    quiet: bool = False

    @property
    def progress(self) -> bool:
        """Whether to show progress (not with ``-q``; the bar itself is silent off a terminal)."""
        return not self.quiet

    def provenance(self, *, columns: Mapping[str, Any] | None = None, units: Mapping[str, str] | None = None, **extra: Any) -> dict[str, Any]:
        """Provenance of this run: the command line, the input files (path, size, sha256), and the
        ``columns`` and ``units`` the command declares."""
        from .results import provenance

        files = [{"path": str(p), "bytes": p.stat().st_size, "sha256": _sha256(p)} for p in self.inputs]
        clean = {k: v for k, v in (columns or {}).items() if v is not None}
        return provenance(command=shlex.join(["gmsfric", *self.argv]), input_files=files, columns=clean, units=units, **extra)

    def _guard(self, path: Path, what: str) -> None:
        for inp in self.inputs:
            if _same_file(path, inp):
                raise DataError(f"{what} {path} is the input file {inp}: refusing to overwrite it")

    def write_json(self, path: str | Path, result: "Result | Mapping[str, Any]") -> Path:
        """Write a result's JSON (or a plain document) atomically to ``path``; ``-`` is standard
        output."""
        from .io import write_text_atomic
        from .results import dumps

        text = result.to_json() if hasattr(result, "to_json") else dumps(result)
        if str(path) == "-":  # standard output, for every command
            sys.stdout.write(text + "\n")
            sys.stdout.flush()
            return Path("-")
        p = Path(path)
        self._guard(p, "output")
        write_text_atomic(p, text + "\n")
        log.info("wrote %s", p)
        return p

    def write_figures(self, directory: str | Path, figures: Mapping[str, "Figure"]) -> list[Path]:
        """Save figures as ``directory/<stem>.png`` (each atomically, never over an input)."""
        from .results import write_figures

        d = Path(directory)
        for stem in figures:
            self._guard(d / f"{stem}.png", "figure")
        paths = write_figures(figures, d)
        log.info("wrote %d figure(s) to %s", len(paths), d)
        return paths


def _check_output_file(p: Path, option: str, inputs: Sequence[Path], text: str | None = None) -> None:
    from .errors import OutputPathError
    from .io import check_output_path

    given = str(p) if text is None else text
    try:
        check_output_path(given, name=option)
    except OutputPathError as exc:
        # the same message with the option as the user typed it (`--json`, not `path`)
        raise DataError(str(exc).replace(f"`{option}`", option, 1)) from None
    real = Path(os.path.realpath(p))
    if real.exists() and not real.is_file():
        # a device or a FIFO (``/dev/null``): written in place, never replaced, so the node itself
        # must be writable, not its directory
        if not os.access(real, os.W_OK):
            raise DataError(f"{option} {given}: cannot write to it (permission denied)")
    elif not os.access(real.parent, os.W_OK | os.X_OK):
        raise DataError(f"{option} {given}: cannot write in {real.parent} (permission denied)")
    else:
        # the output is written beside its target and renamed over it: try that now, not after the work
        try:
            fd, name = tempfile.mkstemp(prefix=f".{real.name}.", suffix=".tmp", dir=real.parent)
            os.close(fd)
            os.unlink(name)
        except OSError as exc:
            raise DataError(f"{option} {given}: cannot create a file in {real.parent} ({exc.strerror or exc})") from None
    for inp in inputs:
        if _same_file(p, inp):
            raise DataError(f"{option} {given} is the input file {inp}: refusing to overwrite it")


def _check_output_dir(p: Path, option: str, inputs: Sequence[Path]) -> None:
    if p.exists():
        if not p.is_dir():
            raise DataError(f"{option} {p}: exists and is not a directory")
        if not os.access(p, os.W_OK | os.X_OK):
            raise DataError(f"{option} {p}: cannot write in it (permission denied)")
        return
    if not p.parent.is_dir():
        raise DataError(f"{option} {p}: directory {p.parent} does not exist")
    if not os.access(p.parent, os.W_OK | os.X_OK):
        raise DataError(f"{option} {p}: cannot create it in {p.parent} (permission denied)")


def _option(dest: str) -> str:
    return "--" + dest.replace("_", "-") if dest not in ("file", "est") else dest.upper()


def _prepare(args: argparse.Namespace, argv: list[str]) -> Run:
    """Check the declared inputs and outputs before any work."""
    from .io import check_input_file

    files: Files = getattr(args, "_files", Files())
    inputs: list[Path] = []
    for dest in files.inputs:
        value = getattr(args, dest, None)
        for v in value if isinstance(value, list) else [value]:
            if v is not None:
                inputs.append(check_input_file(v))
    for dest in files.outputs:
        v = getattr(args, dest, None)
        if v is None or (dest in files.stdout and v == "-"):
            continue
        _check_output_file(Path(v), _option(dest), inputs, text=v)
    for dest in files.output_dirs:
        v = getattr(args, dest, None)
        if v is not None:
            _check_output_dir(Path(v), _option(dest), inputs)
    return Run(getattr(args, "_prog", "gmsfric").removeprefix("gmsfric").strip(), list(argv), inputs, bool(args.quiet))


# ------------------------------------------------------------------------------------------
# main


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _describe_os_error(exc: OSError) -> str:
    what = exc.strerror or _one_line(exc)
    return f"{exc.filename}: {what}" if exc.filename else what


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``gmsfric`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    prog = "gmsfric"
    debug = "--debug" in argv
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s"))
    old_level, old_propagate = log.level, log.propagate
    log.addHandler(handler)
    log.propagate = False
    log.setLevel(logging.INFO)

    def fail(message: str, code: int) -> int:
        if debug and code != 130:
            traceback.print_exc(file=sys.stderr)
        print(f"{prog}: error: {message}" if code != 130 else f"{prog}: interrupted", file=sys.stderr)
        return code

    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        prog = getattr(args, "_prog", prog)
        debug = bool(args.debug)
        if args.quiet and args.verbose:
            raise UsageError(prog, "-q/--quiet and -v/--verbose exclude each other")
        log.setLevel(logging.WARNING if args.quiet else logging.DEBUG if args.verbose else logging.INFO)
        if args.version:
            from . import __version__

            print(__version__)
            return 0
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        run = _prepare(args, argv)
        return int(args.func(args, run) or 0)
    except UsageError as exc:
        prog = exc.prog
        return fail(_one_line(exc), 2)
    except SystemExit as exc:  # --help
        return int(exc.code or 0) if isinstance(exc.code, int) or exc.code is None else 2
    except KeyboardInterrupt:
        return fail("", 130)
    except IdentificationError as exc:
        return fail(_one_line(exc), 1)
    except GmsfricError as exc:
        return fail(_one_line(exc), 2)
    except MemoryError as exc:
        return fail(f"out of memory{': ' + _one_line(exc) if str(exc) else ''}", 2)
    except OSError as exc:
        return fail(_describe_os_error(exc), 2)
    except Exception as exc:  # noqa: BLE001 - the runner turns every error into one line
        return fail(f"internal error, {type(exc).__name__}: {_one_line(exc)} (please report it; --debug shows the traceback)", 2)
    finally:
        log.removeHandler(handler)
        log.setLevel(old_level)
        log.propagate = old_propagate


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
