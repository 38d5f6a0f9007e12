"""Pinned verdicts and numbers (issue 25): the redesign that merges the law layers and the two
analyses must leave every verdict and number of the paper scenario, the two-mass example, the
``check --scenario paper`` command and one law of every registry kind unchanged.

``pins.json`` (next to this file) holds the values the code computed when they were pinned,
each section with the call that produced it (``source``) and the tolerance rules that apply to
it (each with its reason); ``make_pins.py`` computes them. This test recomputes every section
and compares: verdict strings, bools, ints and ``None`` exactly, floats within the field's
relative tolerance (1e-6 unless a rule says why not), never bit for bit. A failure lists every
field that moved as ``section: field: pinned OLD, now NEW``.

Regenerating the pins
---------------------
Only when a change of a verdict or number is intended::

    PYTHONPATH=$PWD MPLBACKEND=Agg python tests/pinned/make_pins.py --check   # what moved
    PYTHONPATH=$PWD MPLBACKEND=Agg python tests/pinned/make_pins.py           # rewrite pins

and list every moved value with its reason in CHANGELOG.md: an unexplained regeneration
defeats the pin.

When the redesign renames or removes an entry point that ``make_pins.py`` calls (the PD form
``analyze(plant, gains, forgetting, ...)``, ``OpenClosedLoopPDLaw``, ``paper_run_designs``), port
the call in ``make_pins.py`` to the new API and leave ``pins.json`` as it is: the pinned values
are the contract, the generator is only how they are reached. The computations run with one
BLAS thread (``make_pins.compute``): on the shared 2-core machine that is 11 s instead of 55 s.
"""

from __future__ import annotations

import make_pins as mp
import pytest

PINS = mp.load_pins()
SECTIONS = list(PINS["sections"])


@pytest.fixture(scope="module")
def cache() -> dict:
    """The expensive stages (paper synthesis, two-mass design, law problem) shared by the
    sections of one run."""
    return {}


@pytest.mark.parametrize("section", SECTIONS)
def test_pinned_section_unchanged(section, cache):
    new = mp.compute(section, cache)
    moved = mp.differences(section, PINS["sections"][section], new)
    assert not moved, (f"{len(moved)} pinned value(s) of {section} moved (source: "
                       f"{PINS['sections'][section]['source']}):\n" + "\n".join(moved))


def test_every_section_is_pinned_and_every_law_kind_has_one():
    """No section was dropped from (or added without) pins.json; the registry's law kinds are
    all pinned (a kind added or removed by the redesign shows here)."""
    assert set(SECTIONS) == set(mp.sections())
    from ilc_analysis.laws import LAW_KINDS

    assert {s.removeprefix("laws.") for s in SECTIONS if s.startswith("laws.")} == \
        set(LAW_KINDS)


def test_pins_use_the_generators_defaults_and_rules():
    """The file's tolerances are those make_pins.py writes (nobody loosened one by hand)."""
    assert PINS["default_rtol"] == mp.RTOL and PINS["default_atol"] == mp.ATOL
    for name, sec in PINS["sections"].items():
        assert sec["tolerances"] == mp._tolerance_rules(name), name


def test_differences_name_the_field_and_both_values():
    """The failure message a redesign sees: the field, the pinned and the new value; a verdict
    compared exactly, a float within its tolerance, a missing and a new field reported."""
    pinned = {"values": {"conditions.norm_2.verdict": "holds", "conditions.norm_2.value": 0.5,
                         "max_error": [1.0, 0.5], "lambda_min": None, "gone": 1},
              "tolerances": [{"field": "max_error", "rtol": 1e-3, "atol": 0.0, "why": "x"}]}
    same = {"conditions.norm_2.verdict": "holds", "conditions.norm_2.value": 0.5 * (1 + 1e-9),
            "max_error": [1.0005, 0.5], "lambda_min": None, "gone": 1}
    assert mp.differences("s", pinned, same) == []
    moved = {"conditions.norm_2.verdict": "marginal", "conditions.norm_2.value": 0.5001,
             "max_error": [1.01, 0.5], "lambda_min": 0.0, "extra": True}
    lines = mp.differences("s", pinned, moved)
    assert "s: conditions.norm_2.verdict: pinned 'holds', now 'marginal'" in lines[0]
    assert "s: conditions.norm_2.value: pinned 0.5, now 0.5001" in lines[1]
    assert "max_error: pinned [1.0, 0.5], now [1.01, 0.5] (rtol 0.001" in lines[2]
    assert "lambda_min: pinned None, now 0.0" in lines[3]
    assert "gone: pinned 1, now MISSING" in lines[4]
    assert "extra: NEW field True" in lines[5]
    assert len(lines) == 6
    # ints and bools are exact, a bool is not an int
    assert not mp._close(38, 39, 1.0, 1.0) and not mp._close(True, 1, 1.0, 1.0)
