"""The toolkit runs without torch (the optional `learn` extra): what needs it says so."""

import subprocess
import sys
import textwrap

import pytest


def _run(code: str) -> subprocess.CompletedProcess:
    # a fresh interpreter in which `import torch` fails, as on an install without the extra
    prelude = textwrap.dedent("""
        import sys
        sys.modules["torch"] = None
    """)
    return subprocess.run([sys.executable, "-c", prelude + textwrap.dedent(code)],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_tracking_runs_without_torch(tmp_path):
    res = _run(f"""
        from pgm.app.cli import main
        code = main(["demo", "--out", r"{tmp_path / 'demo'}", "--frames", "8", "--quiet"])
        assert code == 0, code
        assert "torch" not in [m for m in sys.modules if sys.modules[m] is not None]
    """)
    assert res.returncode == 0, res.stderr[-2000:]


def test_learned_models_say_they_need_the_learn_extra(tmp_path):
    res = _run(f"""
        from pgm.app.cli import main
        raise SystemExit(main(["learn", "gpdm", "--train", r"{tmp_path}", "--out",
                               r"{tmp_path / 'g.npz'}"]))
    """)
    assert res.returncode == 2, res.stderr[-2000:]
    assert "pgm-tracking[learn]" in res.stderr and "Traceback" not in res.stderr
