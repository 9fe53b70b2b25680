"""Every tutorial under docs/ runs as a script on a small input."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("[0-9][0-9]_*.py"))
SKELETONS = sorted((ROOT / "docs" / "skeletons").glob("*.py"))


def test_there_are_tutorials():
    assert TUTORIALS


@pytest.mark.parametrize("script", TUTORIALS, ids=lambda p: p.name)
def test_tutorial_runs(script, tmp_path):
    res = subprocess.run([sys.executable, str(script), "--out", str(tmp_path),
                          "--max-frames", "25"], capture_output=True, text=True, timeout=600,
                         cwd=tmp_path)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-4000:]
    assert "success AUC" in res.stdout or "frames" in res.stdout
    assert any(tmp_path.iterdir())


@pytest.mark.parametrize("script", SKELETONS, ids=lambda p: p.name)
def test_skeleton_runs(script, tmp_path):
    """The copy-me skeletons run as they are (their own asserts check the contract)."""
    res = subprocess.run([sys.executable, str(script), "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-4000:]
    assert "rule calls checked" in res.stdout


def test_readme_example_runs(shared_data, tmp_path, monkeypatch):
    """The README's Python example, as written (outputs redirected to a temp folder)."""
    import re

    text = (ROOT / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    code = code.replace('"../shared/data', f'"{shared_data}')
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102 - our own README
    assert 0.0 <= namespace["result"].metrics["success_auc"] <= 1.0
    assert (tmp_path / "out" / "tracks.txt").is_file() and (tmp_path / "colour_pf.png").is_file()
