"""The README's Python examples run as printed (the first thing a new user copies), and the
quick start uses the front door only (issue 25: ``import ilc_analysis as ilc`` and root names)."""

from __future__ import annotations

import re
from pathlib import Path

import ilc_analysis

README = Path(__file__).resolve().parents[1] / "README.md"


def _blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


def test_quick_start_uses_root_names_only():
    """The first block imports nothing but the package and reads only its root names."""
    quick = _blocks()[0]
    imports = re.findall(r"^(?:import|from) .*$", quick, re.M)
    assert imports == ["import numpy as np", "import control", "import ilc_analysis as ilc"]
    used = set(re.findall(r"\bilc\.(\w+)", quick))
    assert used and used <= set(ilc_analysis.__all__) - {
        "model", "lifting", "problem", "laws", "analysis", "synthesis", "simulation",
        "plotting", "paper", "design", "studies", "exceptions"}, used


def test_readme_python_blocks_run(tmp_path, monkeypatch):
    """Every ```python block, in order, in one namespace (as a user pastes them)."""
    blocks = _blocks()
    assert len(blocks) >= 4, "README has no ```python blocks"
    monkeypatch.chdir(tmp_path)            # the quick start writes its design file
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)   # noqa: S102 - the README's code
    ilc = namespace["ilc"]
    analysis = ilc.analyze(namespace["problem"], namespace["law"])
    assert analysis.monotone          # norm-optimal: T = R/(sigma^2 + R) per direction
    result = namespace["result"]
    assert result.divergence is None and result.dataset.sizes["iteration"] == 10
    pd = namespace["pd"]
    assert pd.status == "optimal" and pd.certificate.holds
    check = ilc.load_design(tmp_path / "pd.toml").check(analysis=False)
    assert check.reproduced and check.holds
    exec(compile(blocks[1], "README.md", "exec"), namespace)   # noqa: S102 - the README's code
    long_analysis = namespace["long_analysis"]      # N = 20 000: the matrix-free engine
    assert long_analysis.settings["engine"] == "operator" and long_analysis.error_monotone
    exec(compile(blocks[2], "README.md", "exec"), namespace)   # noqa: S102 - the README's code
    assert ilc.analyze(namespace["servo"], namespace["law"]).monotone
    assert namespace["result"].divergence is None
    exec(compile(blocks[3], "README.md", "exec"), namespace)   # noqa: S102 - the README's code
    bounded = namespace["result"]
    u = bounded.dataset["u"].values
    assert bounded.divergence is None and abs(u).max() <= 1.5
    assert abs(u[:, 1:] - u[:, :-1]).max() <= 0.05 + 1e-12
    certs = bounded.certificates
    assert len(certs) == 10 and all(c["status"] == "solved" for c in certs)
