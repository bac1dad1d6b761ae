#!/usr/bin/env bash
# Blender as a Python module (bpy 5.0.1 wants Python 3.11), in a venv that
# later runs reuse: the Blender test calls this once per build directory.
# Usage: scripts/blender/setup_bpy.sh VENV_DIR
# Exit 0 with VENV_DIR/bin/python importing bpy; non-zero (with the reason on
# stderr) when there is no Python 3.11 or the wheel cannot be had.
set -u
VENV=${1:?usage: setup_bpy.sh VENV_DIR}
BPY_VERSION=5.0.1
mkdir -p "$(dirname "$VENV")"
exec 9> "$VENV.lock" # two runs that start together install once
flock 9
if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c "import bpy" 2>/dev/null; then
  exit 0
fi
PY=""
for p in python3.11 /root/.pyenv/shims/python3.11 /usr/local/bin/python3.11; do
  if command -v "$p" > /dev/null 2>&1 && "$p" -c "import venv" 2>/dev/null; then PY=$p; break; fi
done
[ -n "$PY" ] || { echo "setup_bpy: no python3.11 found (bpy $BPY_VERSION needs Python 3.11)" >&2; exit 1; }
rm -rf "$VENV"
"$PY" -m venv "$VENV" || { echo "setup_bpy: cannot create a venv with $PY" >&2; exit 1; }
"$VENV/bin/pip" install -q "bpy==$BPY_VERSION" >&2 ||
  { echo "setup_bpy: pip install bpy==$BPY_VERSION failed (offline?)" >&2; exit 1; }
"$VENV/bin/python" -c "import bpy" || { echo "setup_bpy: bpy installed but does not import" >&2; exit 1; }
