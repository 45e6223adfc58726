#!/usr/bin/env bash
# Installs what the Python module and its tests need into the `python3` on PATH
# (or $PYTHON): nanobind and scikit-build-core (build), NumPy and pytest (tests).
# matplotlib is optional (examples/python). Called by scripts/install-deps.sh.
# Idempotent: nothing is downloaded when everything imports already.
set -euo pipefail
PY="${PYTHON:-python3}"

if "$PY" - <<'PYEOF' 2>/dev/null; then
import importlib.metadata as md
import nanobind, numpy, pytest, scikit_build_core  # noqa: F401
assert int(md.version("nanobind").split(".")[0]) >= 2
PYEOF
  exit 0
fi

requirements=("nanobind>=2.0" "scikit-build-core>=0.10" "numpy>=1.22" "pytest>=7")
# Debian's own python3 is "externally managed" (PEP 668): pip needs --break-system-packages
# there (the packages go to /usr/local, apart from Debian's). A venv or pyenv python does not.
if ! "$PY" -m pip install --quiet "${requirements[@]}" 2>/tmp/rpyfmm-pip.err; then
  if grep -q "externally-managed-environment" /tmp/rpyfmm-pip.err; then
    "$PY" -m pip install --quiet --break-system-packages "${requirements[@]}"
  else
    cat /tmp/rpyfmm-pip.err >&2
    exit 1
  fi
fi
