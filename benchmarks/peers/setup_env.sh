#!/usr/bin/env bash
# Create the peer trackers' own virtualenv, .venv-peers/ at the repository root.
#
#   bash benchmarks/peers/setup_env.sh
#
# The peers (OpenCV CSRT / KCF / MIL, SORT / ByteTrack / OC-SORT from the PyPI package
# `trackers`, and Stone Soup's SMC-PHD) are never toolkit dependencies: they run as
# subprocesses in this venv (benchmarks/peers/{mot,sot,phd}_peers.py) and exchange plain
# files with the toolkit's benchmarks (benchmarks/_peers.py), which score their output with
# pgm's own metrics.
#
# Why a separate venv, and why the OpenCV dance below:
#  * `trackers` 2.6.1 requires `opencv-python` (the GUI build); the toolkit uses
#    `opencv-python-headless`. Both wheels install the same `cv2/` package folder, so they
#    cannot live side by side in one environment without one silently overwriting the
#    other's files.
#  * CSRT and KCF exist only in the contrib build (`opencv-contrib-python-headless`);
#    MIL is in every build. The contrib build also writes `cv2/`.
#  * So: install `trackers` (which pulls `opencv-python`), then uninstall `opencv-python`
#    (its uninstall deletes the shared `cv2/` files, whoever wrote them last) and
#    force-reinstall `opencv-contrib-python-headless`, so that exactly one wheel owns
#    `cv2/`. `trackers` only uses the core cv2 API, which the contrib build has too;
#    `pip check` will report the missing `opencv-python` requirement, which is expected.
#  * `trackers` does not need torch (only its optional `mask` extra does), so none is
#    installed here.
#
# OpenCV version: by default the same version as the toolkit venv's opencv-python-headless
# (so MIL is the same code in both venvs), else the newest; override with
# PGM_PEERS_OPENCV=<version>. The venv path can be overridden with PGM_PEERS_VENV.
#
# Idempotent: when the venv already passes the check below, nothing is installed.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
VENV="${PGM_PEERS_VENV:-$ROOT/.venv-peers}"
PYTHON="${PGM_PEERS_BASE_PYTHON:-python3.11}"
TRACKERS_VERSION="2.6.1"
# Stone Soup, the PHD filter's peer (benchmarks/peers/phd_peers.py); optional: when it cannot
# be installed the peer trackers still are, and benchmarks/speed.py says so
STONESOUP_VERSION="1.9.1"

check() {
  [ -x "$VENV/bin/python" ] || return 1
  "$VENV/bin/python" - <<'EOF' 2>/dev/null
import importlib.metadata as md
import numpy as np
import cv2
for name in ("TrackerCSRT_create", "TrackerKCF_create", "TrackerMIL_create"):
    getattr(cv2, name)()
import supervision as sv
import trackers
from trackers import ByteTrackTracker, OCSORTTracker, SORTTracker
assert md.version("trackers") == "2.6.1", md.version("trackers")
# exactly one OpenCV wheel owns cv2/: the contrib headless build
installed = {d.metadata["Name"].lower() for d in md.distributions()}
others = {"opencv-python", "opencv-python-headless", "opencv-contrib-python"} & installed
assert "opencv-contrib-python-headless" in installed and not others, others
det = sv.Detections(xyxy=np.array([[10.0, 10.0, 50.0, 90.0]]), confidence=np.array([0.9]))
for cls in (SORTTracker, ByteTrackTracker, OCSORTTracker):
    t = cls(frame_rate=25.0)
    for _ in range(4):
        out = t.update(det)
    assert len(out) == 1 and int(out.tracker_id[0]) >= 0, (cls, out)
EOF
}

# keep the venv out of git (one line in the root .gitignore)
if ! grep -qxF ".venv-peers/" "$ROOT/.gitignore" 2>/dev/null; then
  echo ".venv-peers/" >> "$ROOT/.gitignore"
fi

ensure_stonesoup() {
  "$VENV/bin/python" -c "import importlib.metadata as m; assert m.version('stonesoup') == '$STONESOUP_VERSION'" \
    2>/dev/null && return 0
  echo "installing stonesoup==$STONESOUP_VERSION into $VENV"
  "$VENV/bin/python" -m pip --disable-pip-version-check install -q "stonesoup==$STONESOUP_VERSION" \
    || echo "stonesoup not installed: the PHD filter's peer is missing (benchmarks/speed.py says so)" >&2
}

if check; then
  ensure_stonesoup
  echo "peer venv OK: $VENV"
  exit 0
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "creating $VENV with $PYTHON"
  "$PYTHON" -m venv "$VENV"
fi
PIP=("$VENV/bin/python" -m pip --disable-pip-version-check)

cv_version="${PGM_PEERS_OPENCV:-}"
if [ -z "$cv_version" ] && [ -x "$ROOT/.venv/bin/python" ]; then
  cv_version="$("$ROOT/.venv/bin/python" -c \
    'import importlib.metadata as m; print(m.version("opencv-python-headless"))' \
    2>/dev/null || true)"
fi
contrib="opencv-contrib-python-headless${cv_version:+==$cv_version}"

echo "installing trackers==$TRACKERS_VERSION and $contrib into $VENV"
"${PIP[@]}" install -q "trackers==$TRACKERS_VERSION" "$contrib"
# trackers pulled opencv-python; remove every other cv2-providing wheel, then reinstall the
# contrib headless build so its cv2/ files are complete (the uninstall deleted shared ones)
"${PIP[@]}" uninstall -q -y opencv-python opencv-python-headless opencv-contrib-python \
  2>/dev/null || true
"${PIP[@]}" install -q --force-reinstall --no-deps "$contrib"

if check; then
  ensure_stonesoup
  echo "peer venv OK: $VENV"
else
  echo "peer venv check FAILED in $VENV; details:" >&2
  "$VENV/bin/python" -c "import cv2, trackers; print(cv2.__version__, cv2.TrackerCSRT_create)" >&2
  exit 1
fi
