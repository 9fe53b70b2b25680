#!/usr/bin/env bash
# Set up a virtual environment (first run only) and run the demo or the test suite.
#   ./run.sh demo [OUT_DIR]      render a synthetic scene, track it, write every output
#   ./run.sh test [PYTEST_ARGS]  run the test suite
set -euo pipefail
cd "$(dirname "$0")"
VENV="${PGM_VENV:-.venv}"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
fi
# shellcheck disable=SC1091
. "$VENV/bin/activate"
stamp="$VENV/.pgm-installed"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  # torch first, pinned: on these machines 2.13.0 is a local CPU wheel; an unpinned
  # torch may pull a multi-GB CUDA build.
  python -c "import torch" 2>/dev/null || pip install -q torch==2.13.0
  pip install -q -e '.[test,learn,cluster]'
  touch "$stamp"
fi
cmd="${1:-}"
shift || true
case "$cmd" in
  demo) exec pgm demo --out "${1:-demo_out}" ;;
  test) exec python -m pytest -q "$@" ;;
  *) echo "usage: ./run.sh demo [OUT_DIR] | ./run.sh test [PYTEST_ARGS]" >&2; exit 2 ;;
esac
