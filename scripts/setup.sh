#!/usr/bin/env bash
# Create .venv and install rasm into it (editable), with pytest: the guides' commands (rasm,
# python, pytest for rasm.testing) all run from .venv/bin. With the test extras, ROS 2's
# included, when asked: setup.sh test.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
    .venv/bin/pip install -q --upgrade pip
fi
if [ "${1:-}" = "test" ]; then
    .venv/bin/pip install -q -e '.[test,ros2]'
else
    .venv/bin/pip install -q -e . 'pytest>=8.0'
fi
