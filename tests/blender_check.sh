#!/usr/bin/env bash
# The Blender test (tests/blender_check.py) in the bpy venv that
# scripts/blender/setup_bpy.sh makes once per build directory. Where bpy
# cannot be had (no Python 3.11, offline) it exits 77, which ctest reports as
# skipped (SKIP_RETURN_CODE), with the reason.
# Usage: blender_check.sh BAKER SCENES_DIR WORKDIR SOURCE_DIR VENV_DIR
set -u
BAKER=$1 SCENES=$2 WORK=$3 SRC=$4 VENV=$5
if ! "$SRC/scripts/blender/setup_bpy.sh" "$VENV"; then
  echo "SKIP: Blender as a Python module (bpy) could not be installed into $VENV"
  exit 77
fi
exec "$VENV/bin/python" "$SRC/tests/blender_check.py" "$BAKER" "$SCENES" "$WORK" "$SRC/scripts/blender"
