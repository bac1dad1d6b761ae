#!/usr/bin/env bash
# Mitsuba 3 (PyPI `mitsuba`, with numpy) in a venv that later runs reuse, for
# the validation against Mitsuba (scripts/bench_mitsuba and the ctest case
# mitsuba_small). About 60 MB of wheels once; seconds when already there.
# Usage: scripts/setup_mitsuba.sh [VENV_DIR]   (default build/mitsuba-venv)
# Exit 0 with VENV_DIR/bin/python importing mitsuba; non-zero (reason on
# stderr) when it cannot be had: the test is then skipped, not failed.
set -u
cd "$(dirname "$0")/.."
VENV=${1:-build/mitsuba-venv}
MITSUBA_VERSION=3.9.1
mkdir -p "$(dirname "$VENV")"
exec 9> "$VENV.lock" # two runs that start together install once
flock 9
if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c "import mitsuba, numpy" 2>/dev/null; then
  exit 0
fi
rm -rf "$VENV"
python3 -m venv "$VENV" || { echo "setup_mitsuba: cannot create a venv with python3" >&2; exit 1; }
"$VENV/bin/pip" install -q "mitsuba==$MITSUBA_VERSION" numpy >&2 ||
  { echo "setup_mitsuba: pip install mitsuba==$MITSUBA_VERSION failed (offline?)" >&2; exit 1; }
"$VENV/bin/python" -c "import mitsuba; mitsuba.set_variant('scalar_rgb')" ||
  { echo "setup_mitsuba: mitsuba installed but does not import" >&2; exit 1; }
