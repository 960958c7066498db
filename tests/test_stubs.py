"""The committed stubs of the compiled module match it (mypy.stubtest)."""

import subprocess
import sys

import pytest


def test_stubs_match_the_compiled_module() -> None:
    pytest.importorskip("mypy")
    proc = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "gmsfric._gmsfric"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
