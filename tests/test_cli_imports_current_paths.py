"""The command line loads its command modules by their current (private) paths: no
``ilc-analysis`` run warns about a deprecated module path of the toolkit itself (issue 25)."""

from __future__ import annotations

import subprocess
import sys


def test_help_loads_every_command_without_a_deprecation_warning():
    run = subprocess.run([sys.executable, "-W", "error::FutureWarning", "-m",
                          "ilc_analysis.cli.main", "--help"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stderr == ""
    assert "study" in run.stdout and "lead-scan" in run.stdout
