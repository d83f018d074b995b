#!/usr/bin/env bash
# Create .venv and install rasm into it (editable, with the test extras when asked: setup.sh test),
# then build its compiled modules.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
    .venv/bin/pip install -q --upgrade pip
fi
if [ "${1:-}" = "test" ]; then
    .venv/bin/pip install -q -e '.[test,compiled]'
else
    .venv/bin/pip install -q -e '.[compiled]'
fi
# Compile the hot modules (rasm/compiled: the Hotbox about 1.45 times faster, same source).
# Without a C compiler rasm runs as plain Python; an edited module runs as plain Python until
# rebuilt.
.venv/bin/python -m rasm.compiled build || echo "warning: rasm runs as plain Python (no compiled build)" >&2
