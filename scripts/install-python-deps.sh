#!/usr/bin/env bash
# Installs what the Python module and its tests need into the `python3` on PATH
# (or $PYTHON): nanobind and scikit-build-core (build), NumPy and pytest (tests), gsd (the GSD
# tests; optional).
# matplotlib is optional (examples/python). Called by scripts/install-deps.sh.
# Idempotent: nothing is downloaded when everything imports already.
set -euo pipefail
PY="${PYTHON:-python3}"

# Debian's own python3 is "externally managed" (PEP 668): pip needs --break-system-packages
# there (the packages go to /usr/local, apart from Debian's). A venv or pyenv python does not.
pip_install() {
  if ! "$PY" -m pip install --quiet "$@" 2>/tmp/rpyfmm-pip.err; then
    if grep -q "externally-managed-environment" /tmp/rpyfmm-pip.err; then
      "$PY" -m pip install --quiet --break-system-packages "$@"
    else
      cat /tmp/rpyfmm-pip.err >&2
      return 1
    fi
  fi
}

if ! "$PY" - <<'PYEOF' 2>/dev/null; then
import importlib.metadata as md
import nanobind, numpy, pytest, scikit_build_core  # noqa: F401
assert int(md.version("nanobind").split(".")[0]) >= 2
PYEOF
  pip_install "nanobind>=2.0" "scikit-build-core>=0.10" "numpy>=1.22" "pytest>=7"
fi
# gsd reads the GSD trajectories in tests/python/test_gsd.py; optional: those tests skip without it.
if ! "$PY" -c "import gsd.hoomd" 2>/dev/null; then
  pip_install gsd || echo "install-python-deps: gsd not installed; the Python GSD tests will skip" >&2
fi
