"""The documentation site builds with ``mkdocs build --strict``: a broken link, a missing anchor or a docstring that
mkdocstrings cannot read fails it; its home page is the README, with the animation and the results table."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_site_builds_strict_with_the_readme_as_home(tmp_path):
    env = os.environ | {"NO_MKDOCS_2_WARNING": "1"}
    command = [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)]
    result = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:]
    home = (tmp_path / "index.html").read_text()
    assert 'src="figures/learned_episode.gif"' in home and (tmp_path / "figures/learned_episode.gif").is_file()
    assert "<table>" in home
    for page in ("env", "training", "results", "performance", "design", "api"):
        assert (tmp_path / page / "index.html").is_file(), f"the site has no {page} page"
    assert "<table>" in (tmp_path / "results" / "index.html").read_text()
    assert "TrainConfig" in (tmp_path / "api" / "index.html").read_text()
