"""The README's set-up commands are the ones CI runs."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bash_blocks(text: str) -> list[str]:
    parts = text.split("```bash\n")[1:]
    return [p.split("```")[0].strip() for p in parts]


def test_first_screen_has_exactly_the_two_setup_commands_and_ci_runs_the_test_one():
    readme = (ROOT / "README.md").read_text()
    first_screen = readme.split("---")[0]
    blocks = _bash_blocks(first_screen)
    assert len(blocks) == 2
    install_and_demo, tests = blocks
    assert "gmsfric demo" in install_and_demo and "pip install" in install_and_demo
    assert "[test]" in tests and "pytest" in tests and "cargo test" in tests
    ci = (ROOT / ".ci" / "run").read_text()
    assert tests in ci.splitlines()
