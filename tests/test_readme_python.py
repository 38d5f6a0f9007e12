"""The README's Python example runs as printed (the first thing a new user copies)."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_block_runs():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
    assert blocks, "README has no ```python block"
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)   # noqa: S102 - the README's code
    analysis = namespace["analyse"](namespace["problem"], namespace["law"])
    assert analysis.monotone          # norm-optimal: T = R/(sigma^2 + R) per direction
    result = namespace["result"]
    assert result.divergence is None and result.dataset.sizes["iteration"] == 10
