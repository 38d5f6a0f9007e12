"""The package checks with exceptions, never with ``assert`` (``python -O`` removes asserts):
bad input raises ParameterError/ShapeError, a broken internal invariant InternalError."""

import ast
from pathlib import Path

import ilc_analysis
from ilc_analysis.exceptions import ILCError, InternalError

PACKAGE = Path(ilc_analysis.__file__).parent


def test_no_assert_statement_in_the_package():
    found = [f"{path.relative_to(PACKAGE.parent)}:{node.lineno}"
             for path in sorted(PACKAGE.rglob("*.py"))
             for node in ast.walk(ast.parse(path.read_text(), str(path)))
             if isinstance(node, ast.Assert)]
    assert not found, f"assert statements (vanish under python -O): {found}"


def test_internal_error_is_an_ilc_error():
    assert issubclass(InternalError, ILCError) and issubclass(InternalError, RuntimeError)
