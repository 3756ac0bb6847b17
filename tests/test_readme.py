"""README.md stays true: its two set-up commands and .ci/run agree with the code (its variable table:
tests/test_generated.py)."""
from __future__ import annotations

import re
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_ci_runs_the_readme_test_command():
    commands = re.findall(r"```sh\n(.*?)\n```", README, re.S)
    test_command = [c for c in commands if "pytest" in c]
    assert len(test_command) == 1
    assert test_command[0] in (ROOT / ".ci" / "run").read_text().splitlines()


def test_main_job_command_uses_the_pipeline_verb():
    commands = re.findall(r"```sh\n(.*?)\n```", README, re.S)
    assert any(c.endswith("imufmu pipeline --out out") for c in commands)
