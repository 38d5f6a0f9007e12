"""The README's Python example runs as printed (the first thing a new user copies)."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_blocks_run():
    """Every ```python block, in order, in one namespace (as a user pastes them)."""
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
    assert len(blocks) >= 2, "README has no ```python blocks"
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)   # noqa: S102 - the README's code
    analysis = namespace["analyze"](namespace["problem"], namespace["law"])
    assert analysis.monotone          # norm-optimal: T = R/(sigma^2 + R) per direction
    result = namespace["result"]
    assert result.divergence is None and result.dataset.sizes["iteration"] == 10
    exec(compile(blocks[1], "README.md", "exec"), namespace)   # noqa: S102 - the README's code
    bounded = namespace["result"]
    u = bounded.dataset["u"].values
    assert bounded.divergence is None and abs(u).max() <= 1.5
    assert abs(u[:, 1:] - u[:, :-1]).max() <= 0.05 + 1e-12
    certs = bounded.certificates
    assert len(certs) == 10 and all(c["status"] == "solved" for c in certs)
