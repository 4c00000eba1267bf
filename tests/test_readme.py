"""The README's two commands are the ones a newcomer can run and CI runs (issue 73): each makes a virtual
environment first (Debian's and Ubuntu's own Python refuses `pip install` outside one, PEP 668), and `.ci/run`
runs the test command word for word."""

import re

from tests.conftest import ROOT


def _commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    return [block.strip() for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S)[:2]]


def test_the_readmes_first_two_commands_make_a_venv_first():
    demo, tests = _commands()
    for command in (demo, tests):
        assert command.startswith("python3 -m venv .venv && . .venv/bin/activate && python3 -m pip install -e "), (
            command
        )
        assert "\n" not in command
    assert demo.endswith("sandbox run melting_block") and tests.endswith("python3 -m pytest")


def test_ci_runs_the_readmes_test_command_word_for_word():
    _, tests = _commands()
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert tests in lines
