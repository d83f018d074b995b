#!/usr/bin/env bash
# Create .venv and install rasm into it (editable, with the test extras when asked: setup.sh test).
#
# The interpreter: $PYTHON when set; otherwise the distribution's /usr/bin/python3 when it is
# 3.11 or newer and can make a venv, else python3 on the PATH. A distribution's interpreter is
# statically linked, where a source build made with --enable-shared (pyenv's, for one) calls
# into libpython through the dynamic linker: the simulated Hotbox runs about 15 % faster on the
# former on the same machine (docs/performance-statecharts.md).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -n "${PYTHON:-}" ]; then
    PY=$PYTHON
elif /usr/bin/python3 -c 'import sys, ensurepip, venv; sys.exit(sys.version_info < (3, 11))' \
        >/dev/null 2>&1; then
    PY=/usr/bin/python3
else
    PY=python3
fi
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
    .venv/bin/pip install -q --upgrade pip
fi
if [ "${1:-}" = "test" ]; then
    .venv/bin/pip install -q -e '.[test]'
else
    .venv/bin/pip install -q -e .
fi
