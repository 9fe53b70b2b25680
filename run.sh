#!/usr/bin/env bash
# Set up a virtual environment (first run only) and run the demo or the test suite.
#   ./run.sh demo [OUT_DIR]      render a synthetic scene, track it, write every output
#   ./run.sh test [PYTEST_ARGS]  run the test suite, a worker per core (e.g. ./run.sh test -m "not slow")
# The demo installs the base package only; the tests install the extras they need
# (test, learn, cluster, docs). PGM_VENV names the environment (default: .venv).
set -euo pipefail
cd "$(dirname "$0")"
cmd="${1:-}"
shift || true
case "$cmd" in
  demo) need="" ;;
  test) need="cluster docs learn test" ;;
  *) echo "usage: ./run.sh demo [OUT_DIR] | ./run.sh test [PYTEST_ARGS]" >&2; exit 2 ;;
esac
VENV="${PGM_VENV:-.venv}"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
fi
# shellcheck disable=SC1091
. "$VENV/bin/activate"
# The stamp records the extras installed, one a line ("base" for none): a venv set up by
# `demo` and later used by `test` gets the missing extras, one set up by `test` serves
# `demo` as it is, and an edited pyproject.toml reinstalls what the stamp lists.
stamp="$VENV/.pgm-installed"
have="" valid=""
if [ -f "$stamp" ] && grep -qx base "$stamp"; then
  have="$( { grep -vx base "$stamp" || true; } | tr '\n' ' ')"
  [ pyproject.toml -nt "$stamp" ] || valid=1
fi
missing=""
for extra in $need; do
  case " $have " in *" $extra "*) ;; *) missing="$missing $extra" ;; esac
done
if [ -z "$valid" ] || [ -n "$missing" ]; then
  want="$(printf '%s\n' $have $need | sort -u | tr '\n' ' ')"
  if [ -n "${want// /}" ]; then
    case " $want " in
      *" learn "*)
        # torch first, pinned: on these machines 2.13.0 is a local CPU wheel; an unpinned
        # torch may pull a multi-GB CUDA build.
        python -c "import torch" 2>/dev/null || pip install -q torch==2.13.0 ;;
    esac
    pip install -q -e ".[$(echo $want | tr ' ' ',')]"
  else
    pip install -q -e .
  fi
  printf '%s\n' base $want > "$stamp"
fi
case "$cmd" in
  demo) exec pgm demo --out "${1:-demo_out}" ;;
  # one worker per core, at most 8 (pytest-xdist; each worker holds its own imports,
  # torch's among them); a later -n in PYTEST_ARGS wins (-n 0: one process)
  test) exec python -m pytest -q -n auto --maxprocesses 8 --dist worksteal "$@" ;;
esac
