"""The runner imports only the module of the command being run, and still lists every command
when asked for help or given an unknown one."""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest

from gmsfric.cli import COMMANDS

PROBE = """
import contextlib, io, sys
from gmsfric.cli import COMMANDS, main
with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
    code = main(sys.argv[1:])
loaded = sorted(m for m in set(COMMANDS.values()) if m in sys.modules)
print(code, ",".join(loaded), repr(out.getvalue() + err.getvalue()))
"""


def _run(*argv: str) -> tuple[int, set[str], str]:
    proc = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, timeout=120, check=True)
    code, loaded, text = proc.stdout.strip().split(" ", 2)
    return int(code), set(filter(None, loaded.split(","))), ast.literal_eval(text)


@pytest.mark.parametrize("command", ["loop", "glitch", "paper"])
def test_a_command_imports_only_its_own_module(command):
    code, loaded, text = _run("-q", command, "--help")
    assert code == 0 and f"gmsfric {command}" in text
    assert loaded == {COMMANDS[command]}


def test_version_imports_no_command():
    code, loaded, text = _run("--version")
    assert code == 0 and text.strip() and loaded == set()


@pytest.mark.parametrize("argv", [["--help"], ["lop"], [], ["--", "loop"]])
def test_help_and_unknown_commands_list_every_command(argv):
    code, loaded, text = _run(*argv)
    assert loaded == set(COMMANDS.values())
    assert all(name in text for name in COMMANDS)
    assert code == (0 if argv == ["--help"] else 2)
