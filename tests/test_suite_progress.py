"""The suite shows its progress (issue 37): a stuck test fails by name within the per-test limit
and the suite goes on; the slowest tests are listed at the end; the output is one line per file.

The mechanism is demonstrated on a throw-away test file run by a child pytest with this
repository's configuration (pyproject.toml), the limit lowered to two seconds so that the
demonstration is quick; the rule that gives tests marked slow a longer limit
(tests/conftest.py) is checked on a test of this file.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: the child's per-test limit [s] (the suite's own is [tool.pytest.ini_options] timeout)
CHILD_LIMIT = 2
#: how long the stuck test would sleep if nothing stopped it [s]
STUCK_FOR = 600

_TESTS = f"""
import time


def test_quick():
    pass


def test_stuck_forever():
    time.sleep({STUCK_FOR})


def test_after_the_stuck_one():
    pass
"""

def _options() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]


def test_the_suite_declares_a_per_test_limit_durations_and_per_file_progress(pytestconfig):
    options = _options()
    assert 60 <= options["timeout"] <= 1800          # generous, yet a stuck test is named
    assert "--durations=" in options["addopts"]
    assert options["console_output_style"] in ("progress", "times", "count")
    # the plugin is active in this very run, with the configured limit (or one given to it)
    assert pytestconfig.pluginmanager.hasplugin("timeout")
    assert float(pytestconfig.getini("timeout")) == options["timeout"]
    make_test = (ROOT / "Makefile").read_text().split("\ntest:", 1)[1].split("\n\n", 1)[0]
    assert "pytest" in make_test and " -q" not in make_test, make_test   # not only dots


def test_a_stuck_test_fails_by_name_and_the_suite_goes_on(tmp_path):
    (tmp_path / "test_demo.py").write_text(_TESTS)
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-c", str(ROOT / "pyproject.toml"),
         "--rootdir", str(tmp_path), "-p", "no:cacheprovider", "-o",
         f"timeout={CHILD_LIMIT}", str(tmp_path / "test_demo.py")],
        capture_output=True, text=True, cwd=tmp_path, timeout=STUCK_FOR // 2, check=False)
    out = done.stdout + done.stderr
    assert done.returncode == 1, out
    assert "FAILED test_demo.py::test_stuck_forever" in out, out
    assert f"Timeout (>{CHILD_LIMIT:.1f}s)" in out, out
    assert "1 failed, 2 passed" in out, out           # the suite went on after it
    # one line per file with its progress, and the slowest tests named at the end
    assert "test_demo.py .F." in out, out
    assert "test_demo.py::test_stuck_forever" in out.split("slowest", 1)[1], out


@pytest.mark.slow
def test_a_test_marked_slow_gets_the_longer_limit(request):
    """tests/conftest.py gives a slow test SLOW_TEST_TIMEOUT (this one is marked only to be
    checked: it takes no time)."""
    from conftest import SLOW_TEST_TIMEOUT

    assert SLOW_TEST_TIMEOUT > _options()["timeout"]
    assert request.node.get_closest_marker("timeout").args == (SLOW_TEST_TIMEOUT,)


def test_property_tests_draw_the_same_examples_on_every_run_without_a_deadline():
    """The suite's hypothesis profile (tests/conftest.py): derandomized, no per-example deadline,
    unless ILC_HYPOTHESIS_PROFILE=explore asks for fresh draws."""
    import os

    from hypothesis import settings

    if os.environ.get("ILC_HYPOTHESIS_PROFILE", "suite") == "suite":
        assert settings.default.derandomize is True
    assert settings.default.deadline is None


def test_an_unknown_hypothesis_profile_is_refused_by_name():
    """A mistyped ILC_HYPOTHESIS_PROFILE stops the run naming the variable and the choices."""
    import os

    env = {**os.environ, "ILC_HYPOTHESIS_PROFILE": "fast"}
    this = "tests/test_suite_progress.py::test_property_tests_draw_the_same_examples_on_every_" \
           "run_without_a_deadline"
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          "-p", "no:xdist", this], capture_output=True, text=True, env=env,
                         cwd=ROOT, timeout=600)
    assert out.returncode != 0
    assert "ILC_HYPOTHESIS_PROFILE must be one of ['explore', 'suite']; got 'fast'" in \
        out.stdout + out.stderr
