"""Issue 26, item 5: every ``--help`` of ``pgm`` shows every option's default, and
``pgm track --help`` says that a camera index or a stream URL is a source."""

from __future__ import annotations

import argparse

import pytest

from pgm.app.cli import build_parser, main


def _parsers(parser: argparse.ArgumentParser, path=("pgm",)):
    """``(command path, parser)`` of ``parser`` and every sub-command under it."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, path + (name,))


PARSERS = list(_parsers(build_parser()))


def _help_of(parser, action) -> str:
    """The help text of ``action`` as ``--help`` prints it (``%(default)s`` expanded)."""
    formatter = parser._get_formatter()
    return " ".join(formatter._expand_help(action).split()) if action.help else ""


def _takes_a_value(action) -> bool:
    return (bool(action.option_strings) and action.nargs != 0 and not action.required
            and not isinstance(action, (argparse._HelpAction, argparse._VersionAction)))


def test_every_command_is_walked():
    names = {" ".join(path) for path, _ in PARSERS}
    for cmd in ("pgm track", "pgm eval", "pgm graph", "pgm learn dbn", "pgm learn gpdm",
                "pgm demo", "pgm view", "pgm bench", "pgm report"):
        assert cmd in names


@pytest.mark.parametrize("path, parser", PARSERS, ids=[" ".join(p) for p, _ in PARSERS])
def test_every_option_shows_its_default(path, parser):
    missing = []
    for action in parser._actions:
        if not _takes_a_value(action):
            continue
        text = _help_of(parser, action)
        if "default" not in text.lower():
            missing.append(f"{action.option_strings[0]}: {text!r}")
    assert not missing, f"{' '.join(path)}: options without a default in --help: {missing}"


def test_help_prints_the_defaults(capsys):
    """The printed page (not only the action's text) carries the values."""
    for argv, needles in [(["track", "--help"], ["(default: 0)", "(default: every frame)"]),
                          (["demo", "--help"], ["(default: 0)", "(default: 90)",
                                                "(default: 100)"]),
                          (["bench", "--help"], ["(default: 1)", "(default: local)"])]:
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 0
        page = " ".join(capsys.readouterr().out.split())
        for needle in needles:
            assert needle in page, (argv, needle)
        assert "(default: None)" not in page and "(default: False)" not in page


def test_track_help_names_cameras_and_stream_urls(capsys):
    with pytest.raises(SystemExit):
        main(["track", "--help"])
    page = " ".join(capsys.readouterr().out.split())
    assert "camera index" in page
    assert "stream URL" in page and "rtsp://" in page


def test_examples_keep_their_line_breaks(capsys):
    """An epilog of examples is printed line by line, a one-line description wrapped."""
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    out = capsys.readouterr().out
    assert "\n  pgm bench docs/experiments/example.toml --out bench_out --jobs 2\n" in out
    with pytest.raises(SystemExit):
        main(["view", "--help"])
    assert max(len(line) for line in capsys.readouterr().out.splitlines()) <= 100


def test_model_names_in_the_help_are_the_models(capsys):
    """The parser lists the models by their entry points, without importing them; each
    name loads a config of that name."""
    from pgm.app.cli import main
    from pgm.models import get_config, model_names

    names = model_names()
    assert {"single-object", "vb-phd", "gpdm", "linear-gaussian"} <= set(names)
    assert all(get_config(n).name == n for n in names)
    with pytest.raises(SystemExit):
        main(["track", "--help"])
    text = " ".join(capsys.readouterr().out.split()).replace("- ", "-")  # wrapped at hyphens
    assert ", ".join(names) in text


def test_building_the_parser_imports_no_model():
    import subprocess
    import sys

    code = ("import sys; from pgm.app.cli import build_parser; build_parser(); "
            "print(sorted(m for m in sys.modules if m.startswith(('pgm.models.', "
            "'pgm.inference', 'torch', 'sklearn', 'matplotlib', 'av')) "
            "and m != 'pgm.models.config'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def test_the_model_is_found_whatever_the_order_of_the_options(tmp_path, capsys):
    """A model's option before the source or the model name is not taken for either; a
    MOTChallenge folder's default model is found for --help too."""
    from pgm.app.cli import model_config_for

    seq = tmp_path / "seq"
    (seq / "det").mkdir(parents=True)
    (seq / "det" / "det.txt").write_text("1,-1,1,1,5,5,1\n")
    from pgm.models import DEFAULT_MULTI_TARGET

    assert model_config_for(["track", str(seq), "--help"]).name == DEFAULT_MULTI_TARGET
    assert model_config_for(["track", "--appearance-weight", "0.5", str(seq), "--out",
                             "o"]).name == DEFAULT_MULTI_TARGET
    assert model_config_for(["track", "--scores", "off", str(seq), "--model", "vb-phd",
                             "--out", "o"]).name == "vb-phd"
    assert model_config_for(["track", "--parts", "2", str(seq), "--model", "part-graph",
                             "--out", "o"]).name == "part-graph"
    assert model_config_for(["graph", "--parts", "2", "multi-pf", "--out", "g"]).name == \
        "multi-pf"
    assert main(["graph", "--parts", "2", "multi-pf", "--out", str(tmp_path / "g.dot")]) == 0
    assert (tmp_path / "g.dot").read_text().startswith("graph")
